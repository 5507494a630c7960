//! Per-vertex maps painted on a Bevy mesh (feature `render`): a muscle
//! built from a `Handle<Mesh>` ([`crate::build::MuscleSource::Handle`])
//! takes its Sliding / Soft / Hard weights, mass multipliers, combed
//! fibres, tendon mask and damping multipliers from these vertex attributes when the mesh has them, or its
//! weights from the vertex colours ([`MapsFromMesh::colors`]). Bevy splits
//! vertices at UV seams; the plug-in welds them and each welded vertex
//! takes the value of the first of its copies.
//!
//! ```
//! use bevy::prelude::*;
//! use sinew_bevy::mesh_maps::ATTRIBUTE_HARD_WEIGHT;
//!
//! let mut mesh = Sphere::new(0.02).mesh().ico(2).unwrap();
//! let count = mesh.count_vertices();
//! // No Hard connection anywhere on this muscle.
//! mesh.insert_attribute(ATTRIBUTE_HARD_WEIGHT, vec![0.0f32; count]);
//! ```

use crate::events::MeshAssetProblem;
use bevy::mesh::{MeshVertexAttribute, VertexAttributeValues, VertexFormat};
use bevy::prelude::*;
use sinew_core::mesh::SurfaceMesh;
use sinew_core::muscle::VertexMaps;

/// Sliding weight per vertex (`f32`, `[0, ∞)`; replaces the muscle's
/// default weight).
pub const ATTRIBUTE_SLIDING_WEIGHT: MeshVertexAttribute =
    MeshVertexAttribute::new("Sinew_SlidingWeight", 0x51e3_0001, VertexFormat::Float32);
/// Soft weight per vertex (`f32`, `[0, ∞)`).
pub const ATTRIBUTE_SOFT_WEIGHT: MeshVertexAttribute =
    MeshVertexAttribute::new("Sinew_SoftWeight", 0x51e3_0002, VertexFormat::Float32);
/// Hard weight per vertex (`f32`, `[0, ∞)`).
pub const ATTRIBUTE_HARD_WEIGHT: MeshVertexAttribute =
    MeshVertexAttribute::new("Sinew_HardWeight", 0x51e3_0003, VertexFormat::Float32);
/// Mass multiplier per vertex (`f32`, `> 0`).
pub const ATTRIBUTE_MASS_SCALE: MeshVertexAttribute =
    MeshVertexAttribute::new("Sinew_MassScale", 0x51e3_0004, VertexFormat::Float32);
/// Combed fibre direction per vertex (`[f32; 3]`, the muscle's frame; a
/// zero vector keeps the computed fibre).
pub const ATTRIBUTE_FIBER: MeshVertexAttribute =
    MeshVertexAttribute::new("Sinew_Fiber", 0x51e3_0005, VertexFormat::Float32x3);

/// Tendon mask per vertex (`f32`, `[0, 1]`; 1: tendon, which neither
/// shortens nor bulges with activation).
pub const ATTRIBUTE_TENDON_MASK: MeshVertexAttribute =
    MeshVertexAttribute::new("Sinew_TendonMask", 0x51e3_0006, VertexFormat::Float32);
/// Damping multiplier per vertex (`f32`, `≥ 0`) of the muscle's damping rate.
pub const ATTRIBUTE_DAMPING_SCALE: MeshVertexAttribute =
    MeshVertexAttribute::new("Sinew_DampingScale", 0x51e3_0007, VertexFormat::Float32);
/// Thickness per vertex (`f32`, scene units, `≥ 0`) of what lies under a
/// skin (its fat): how close the vertex may come to what it slides on
/// ([`VertexMaps::thickness`]).
pub const ATTRIBUTE_THICKNESS: MeshVertexAttribute =
    MeshVertexAttribute::new("Sinew_Thickness", 0x51e3_0008, VertexFormat::Float32);

/// Where a mesh's maps come from, beyond the sinew attributes above.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MapsFromMesh {
    /// Read the Sliding, Soft and Hard weights from the vertex colours'
    /// red, green and blue (a sinew weight attribute wins over its
    /// colour). Default: `false`.
    pub colors: bool,
}

/// Converts a Bevy triangle mesh into a welded [`SurfaceMesh`] and the
/// per-vertex maps its attributes carry (see the module docs).
pub fn surface_and_maps(
    name: &str,
    mesh: &Mesh,
    from: MapsFromMesh,
) -> Result<(SurfaceMesh, VertexMaps), MeshAssetProblem> {
    if mesh.primitive_topology() != bevy::mesh::PrimitiveTopology::TriangleList {
        return Err(MeshAssetProblem::NotTriangles);
    }
    let Some(VertexAttributeValues::Float32x3(positions)) =
        mesh.attribute(Mesh::ATTRIBUTE_POSITION)
    else {
        return Err(MeshAssetProblem::NoPositions);
    };
    let positions: Vec<Vec3> = positions.iter().map(|&p| Vec3::from(p)).collect();
    let indices: Vec<u32> = match mesh.indices() {
        Some(i) => i.iter().map(|i| i as u32).collect(),
        None => (0..positions.len() as u32).collect(),
    };
    let polygons: Vec<Vec<u32>> = indices.chunks_exact(3).map(<[u32]>::to_vec).collect();
    let raw = SurfaceMesh::new(name, positions, &polygons)?;
    let tolerance = raw.bounding_box_diagonal() * 1e-6;
    let (welded, remap) = raw.welded(tolerance)?;
    // Each welded vertex takes its first copy's value.
    let n = welded.vertex_count();
    let carry = |values: Vec<f32>| -> Vec<f32> {
        let mut out = vec![f32::NAN; n];
        for (i, &w) in remap.iter().enumerate() {
            if out[w as usize].is_nan() {
                out[w as usize] = values[i];
            }
        }
        out
    };
    let scalar =
        |attribute: MeshVertexAttribute, color: Option<usize>| match mesh.attribute(attribute) {
            Some(VertexAttributeValues::Float32(values)) => Some(carry(values.clone())),
            _ => match (color, mesh.attribute(Mesh::ATTRIBUTE_COLOR)) {
                (Some(c), Some(VertexAttributeValues::Float32x4(colors))) if from.colors => {
                    Some(carry(colors.iter().map(|rgba| rgba[c]).collect()))
                }
                _ => None,
            },
        };
    let fibers = match mesh.attribute(ATTRIBUTE_FIBER) {
        Some(VertexAttributeValues::Float32x3(values)) => {
            let (x, y, z) = (
                carry(values.iter().map(|v| v[0]).collect()),
                carry(values.iter().map(|v| v[1]).collect()),
                carry(values.iter().map(|v| v[2]).collect()),
            );
            Some((0..n).map(|i| Vec3::new(x[i], y[i], z[i])).collect())
        }
        _ => None,
    };
    let maps = VertexMaps {
        sliding: scalar(ATTRIBUTE_SLIDING_WEIGHT, Some(0)),
        soft: scalar(ATTRIBUTE_SOFT_WEIGHT, Some(1)),
        hard: scalar(ATTRIBUTE_HARD_WEIGHT, Some(2)),
        fibers,
        mass: scalar(ATTRIBUTE_MASS_SCALE, None),
        tendon: scalar(ATTRIBUTE_TENDON_MASK, None),
        damping: scalar(ATTRIBUTE_DAMPING_SCALE, None),
        thickness: scalar(ATTRIBUTE_THICKNESS, None),
    };
    Ok((welded, maps))
}
