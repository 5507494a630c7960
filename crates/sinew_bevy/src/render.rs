//! Rendering (feature `render`): every muscle gets a Bevy [`Mesh`] whose
//! positions and normals are rewritten each frame, and a material tinted by
//! its activation; a surface layer (a simulated skin) gets a skin-coloured
//! material instead; every bone with a target mesh gets a mesh too. Which
//! of them are drawn: [`crate::view::SinewView`].
//!
//! Without a `PbrPlugin` (headless apps) these systems do nothing.

use crate::SinewSystems;
use crate::components::*;
use crate::events::MeshAssetProblem;
use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use sinew_core::closest::{TargetSource, TargetSurface};
use sinew_core::mesh::{SurfaceMesh, vertex_normals};
use std::time::Instant;

/// Colours a muscle's material between `relaxed` (activation 0) and
/// `active` (activation 1).
#[derive(Component, Clone, Copy, Debug, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct ActivationTint {
    /// Colour at rest.
    pub relaxed: Color,
    /// Colour at full activation.
    pub active: Color,
}

impl Default for ActivationTint {
    fn default() -> Self {
        Self {
            relaxed: Color::srgb(0.72, 0.28, 0.26),
            active: Color::srgb(1.0, 0.78, 0.2),
        }
    }
}

/// Marks the muscle meshes this module created (and so rewrites).
#[derive(Component, Clone, Debug)]
pub struct MuscleMesh(pub Handle<Mesh>);

/// Marks the mesh of a simulated surface layer (a skin:
/// [`MuscleParams::is_surface_layer`](sinew_core::muscle::MuscleParams::is_surface_layer)),
/// drawn in [`SkinLayerMesh::COLOR`] rather than tinted by activation.
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct SkinLayerMesh;

impl SkinLayerMesh {
    /// The colour skin layers are drawn in.
    pub const COLOR: Color = Color::srgb(0.86, 0.66, 0.55);
}

/// Marks the meshes this module gave bones (drawn when
/// [`SinewView::bones`](crate::view::SinewView::bones) is on).
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct BoneMesh;

pub(crate) fn register(app: &mut App) {
    app.init_resource::<crate::view::SinewView>()
        .register_type::<crate::view::SinewView>()
        .add_systems(
            PostUpdate,
            (crate::view::apply_xray, crate::view::apply_visibility),
        )
        .register_type::<ActivationTint>()
        .register_type::<TargetFromMesh>()
        .add_systems(
            crate::SinewStepSchedule,
            (
                (add_muscle_meshes, add_bone_meshes).before(SinewSystems::ReadInputs),
                (write_muscle_meshes, tint_muscles).in_set(SinewSystems::WriteBack),
            ),
        )
        .add_systems(
            crate::SinewPrepareSchedule,
            // Before builds start: a muscle that targets the mesh finds
            // the bone's target (unordered, the result hung on the order
            // the executor happened to pick).
            targets_from_meshes
                .before(crate::build::start_builds)
                .before(SinewSystems::AnimateBones),
        );
}

/// Makes any entity with a [`Mesh3d`] a bone muscles can slide on: once its
/// mesh asset is loaded, the entity gets a [`BoneTarget`] of that mesh (in
/// the entity's own space, moved with its transform) and, if it has none, a
/// [`SinewBone`]. Name it in a muscle's targets
/// ([`crate::build::MuscleBuilder::target`]). Entities of one mesh asset (a
/// crowd's bones) share one geometry: the target is built once per asset
/// and the others share it ([`TargetSurface::sharing_geometry`]), as the
/// bones of a scene spawned several times do. A mesh sinew cannot use is
/// reported in [`crate::events::SinewLog`] and the marker removed.
#[derive(Component, Clone, Copy, Debug, Default, Reflect)]
#[reflect(Component, Default)]
pub struct TargetFromMesh;

/// An entity waiting to become a bone: its mesh, name, and whether it is a
/// bone already.
type PendingTarget = (
    Entity,
    &'static Mesh3d,
    Option<&'static Name>,
    Has<SinewBone>,
);

/// The bone targets [`TargetFromMesh`] built, by mesh asset, for the next
/// entity of the same mesh to share. An entry is shared only while the
/// asset's surface is the one it was built from, to the bit (a mesh edited
/// in place gets a target of its own, which replaces the entry), and is
/// dropped once its asset is gone.
#[derive(Default)]
struct TargetsByMesh(bevy::platform::collections::HashMap<AssetId<Mesh>, TargetSurface>);

fn targets_from_meshes(
    mut commands: Commands,
    pending: Query<PendingTarget, With<TargetFromMesh>>,
    meshes: Option<Res<Assets<Mesh>>>,
    mut built: Local<TargetsByMesh>,
    mut log: ResMut<crate::events::SinewLog>,
) {
    let Some(meshes) = meshes else {
        return;
    };
    built.0.retain(|&id, _| meshes.contains(id));
    for (entity, handle, name, is_bone) in &pending {
        let Some(mesh) = meshes.get(&handle.0) else {
            continue; // not loaded yet
        };
        let name = name.map_or_else(|| format!("{entity}"), |n| n.to_string());
        let mut e = commands.entity(entity);
        e.remove::<TargetFromMesh>();
        match surface_from_mesh(&name, mesh) {
            Ok(surface) => {
                let source = TargetSource::Bone(0);
                let target = match built.0.get(&handle.id()) {
                    Some(first) if first.is_rigid_of(&surface.positions, &surface.triangles) => {
                        first.sharing_geometry(name.clone(), source)
                    }
                    _ => {
                        let (positions, triangles) = (surface.positions, surface.triangles);
                        let target = TargetSurface::new(name.clone(), source, positions, triangles);
                        built.0.insert(handle.id(), target.clone());
                        target
                    }
                };
                e.insert(BoneTarget(target));
                if !is_bone {
                    e.insert(SinewBone::new(name));
                }
            }
            Err(problem) => {
                error!("sinew: mesh of '{name}' cannot be a bone target: {problem}");
                log.push(format!("no bone target from '{name}': {problem}"));
            }
        }
    }
}

/// Converts a Bevy triangle mesh into a [`SurfaceMesh`], welding the
/// vertices Bevy splits at UV seams (its maps:
/// [`crate::mesh_maps::surface_and_maps`]).
pub fn surface_from_mesh(name: &str, mesh: &Mesh) -> Result<SurfaceMesh, MeshAssetProblem> {
    let from = crate::mesh_maps::MapsFromMesh::default();
    Ok(crate::mesh_maps::surface_and_maps(name, mesh, from)?.0)
}

fn triangle_mesh(positions: &[Vec3], triangles: &[[u32; 3]]) -> Mesh {
    let mut normals = Vec::new();
    vertex_normals(triangles, positions, &mut normals);
    Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::MAIN_WORLD | RenderAssetUsages::RENDER_WORLD,
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_POSITION,
        positions.iter().map(|p| p.to_array()).collect::<Vec<_>>(),
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_NORMAL,
        normals.iter().map(|n| n.to_array()).collect::<Vec<_>>(),
    )
    .with_inserted_indices(Indices::U32(triangles.iter().flatten().copied().collect()))
}

/// Gives new muscles a mesh and a material of their own.
fn add_muscle_meshes(
    mut commands: Commands,
    muscles: Query<(Entity, &MuscleState, Option<&ActivationTint>), Without<MuscleMesh>>,
    meshes: Option<ResMut<Assets<Mesh>>>,
    materials: Option<ResMut<Assets<StandardMaterial>>>,
) {
    let (Some(mut meshes), Some(mut materials)) = (meshes, materials) else {
        return;
    };
    for (entity, state, tint) in &muscles {
        let m = &state.muscle;
        let handle = meshes.add(triangle_mesh(m.surface_positions(), &m.mesh.triangles));
        let layer = m.params.is_surface_layer();
        let tint = tint.copied().unwrap_or_default();
        let material = materials.add(StandardMaterial {
            base_color: if layer {
                SkinLayerMesh::COLOR
            } else {
                tint.relaxed
            },
            perceptual_roughness: if layer { 0.7 } else { 0.55 },
            double_sided: true,
            cull_mode: None,
            ..default()
        });
        let mut e = commands.entity(entity);
        e.insert((
            MuscleMesh(handle.clone()),
            Mesh3d(handle),
            MeshMaterial3d(material),
            // Vertices are world positions.
            Transform::IDENTITY,
        ));
        if layer {
            e.insert(SkinLayerMesh);
        } else {
            e.insert(tint);
        }
    }
}

/// Bones whose target was just added and that have no mesh yet.
type NewBoneWithoutMesh = (Added<BoneTarget>, Without<Mesh3d>);

/// Gives bones with a target mesh a mesh (bone-coloured).
fn add_bone_meshes(
    mut commands: Commands,
    bones: Query<(Entity, &BoneTarget), NewBoneWithoutMesh>,
    meshes: Option<ResMut<Assets<Mesh>>>,
    materials: Option<ResMut<Assets<StandardMaterial>>>,
    mut bone_material: Local<Option<Handle<StandardMaterial>>>,
) {
    let (Some(mut meshes), Some(mut materials)) = (meshes, materials) else {
        return;
    };
    for (entity, target) in &bones {
        let material = bone_material
            .get_or_insert_with(|| {
                materials.add(StandardMaterial {
                    base_color: Color::srgb(0.89, 0.86, 0.78),
                    perceptual_roughness: 0.8,
                    ..default()
                })
            })
            .clone();
        let t = &target.0;
        let mesh = meshes.add(triangle_mesh(t.positions(), t.triangles()));
        commands
            .entity(entity)
            .insert((Mesh3d(mesh), MeshMaterial3d(material), BoneMesh));
    }
}

/// Rewrites positions and normals of every muscle mesh.
fn write_muscle_meshes(
    muscles: Query<(&MuscleState, &MuscleMesh)>,
    meshes: Option<ResMut<Assets<Mesh>>>,
    mut timings: ResMut<crate::SinewTimings>,
    mut normals: Local<Vec<Vec3>>,
) {
    let Some(mut meshes) = meshes else { return };
    let start = Instant::now();
    for (state, handle) in &muscles {
        let Some(mut mesh) = meshes.get_mut(&handle.0) else {
            continue;
        };
        let m = &state.muscle;
        let positions = m.surface_positions();
        vertex_normals(&m.mesh.triangles, positions, &mut normals);
        if let Some(VertexAttributeValues::Float32x3(out)) =
            mesh.attribute_mut(Mesh::ATTRIBUTE_POSITION)
        {
            for (o, p) in out.iter_mut().zip(positions) {
                *o = p.to_array();
            }
        }
        if let Some(VertexAttributeValues::Float32x3(out)) =
            mesh.attribute_mut(Mesh::ATTRIBUTE_NORMAL)
        {
            for (o, n) in out.iter_mut().zip(normals.iter()) {
                *o = n.to_array();
            }
        }
    }
    timings.step.write_back += start.elapsed();
}

/// Colours each muscle by its activation.
fn tint_muscles(
    muscles: Query<(
        &MuscleState,
        &ActivationTint,
        &MeshMaterial3d<StandardMaterial>,
    )>,
    materials: Option<ResMut<Assets<StandardMaterial>>>,
) {
    let Some(mut materials) = materials else {
        return;
    };
    for (state, tint, material) in &muscles {
        let a = state.muscle.params.activation.clamp(0.0, 1.0);
        let color = tint.relaxed.mix(&tint.active, a);
        if let Some(m) = materials.get(&material.0)
            && m.base_color == color
        {
            continue;
        }
        if let Some(mut m) = materials.get_mut(&material.0) {
            m.base_color = color;
        }
    }
}
