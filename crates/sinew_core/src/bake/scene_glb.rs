//! The bake's `.glb`: every muscle's surface at the first baked frame and
//! every bone (its mesh, if it has one) with its pose animated over the bake,
//! in metres. The muscles' motion is in their `.pc2` caches, whose file names
//! the muscle nodes carry in their `extras` (`"sinew_pc2"`); `extras` also
//! give each node's index among the solver's muscles (`"sinew_muscle"`) or
//! bones (`"sinew_bone"`), for tools that match them by position in a list.

use crate::glb_container::{BinaryBuffer, FLOAT, assemble, floats};
use glam::{Affine3A, Quat, Vec3};
use serde_json::{Value, json};

/// A mesh as written: positions in metres, triangles.
#[derive(Clone, Debug)]
pub(super) struct MeshRecord {
    pub name: String,
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    /// File name of the mesh's `.pc2` cache, when one is written.
    pub cache: Option<String>,
}

/// A bone as written: its mesh in its own frame (metres), if any.
#[derive(Clone, Debug)]
pub(super) struct BoneRecord {
    pub name: String,
    pub mesh: Option<MeshRecord>,
}

/// Material indices of the document.
const MUSCLE_MATERIAL: usize = 0;
const BONE_MATERIAL: usize = 1;

/// The `.glb` bytes: `muscles` at rest, `bones` posed by `poses` (per frame,
/// per bone, translations in metres), frames `dt` seconds apart.
pub(super) fn to_bytes(
    name: &str,
    muscles: &[MeshRecord],
    bones: &[BoneRecord],
    poses: &[Vec<Affine3A>],
    dt: f32,
) -> Vec<u8> {
    let mut buffer = BinaryBuffer::default();
    let mut meshes = Vec::new();
    let mut mesh_of = |buffer: &mut BinaryBuffer, mesh: &MeshRecord, material: usize| {
        let position = buffer.positions(&mesh.positions);
        let normal = buffer.normals(&mesh.triangles, &mesh.positions);
        let indices = buffer.indices(&mesh.triangles);
        meshes.push(json!({
            "name": mesh.name,
            "primitives": [{
                "attributes": { "POSITION": position, "NORMAL": normal },
                "indices": indices,
                "material": material,
                "mode": 4,
            }],
        }));
        meshes.len() - 1
    };

    let mut nodes: Vec<Value> = Vec::new();
    for (m, muscle) in muscles.iter().enumerate() {
        let mesh = mesh_of(&mut buffer, muscle, MUSCLE_MATERIAL);
        let mut node =
            json!({ "name": muscle.name, "mesh": mesh, "extras": { "sinew_muscle": m } });
        if let Some(cache) = &muscle.cache {
            node["extras"]["sinew_pc2"] = json!(cache);
        }
        nodes.push(node);
    }
    let first_bone = nodes.len();
    for (b, bone) in bones.iter().enumerate() {
        let (scale, rotation, translation) = poses[0][b].to_scale_rotation_translation();
        let mut node = json!({
            "name": bone.name,
            "translation": translation.to_array(),
            "rotation": rotation.to_array(),
            "extras": { "sinew_bone": b },
        });
        if !scale.abs_diff_eq(Vec3::ONE, 1e-6) {
            node["scale"] = json!(scale.to_array());
        }
        if let Some(mesh) = &bone.mesh {
            node["mesh"] = json!(mesh_of(&mut buffer, mesh, BONE_MATERIAL));
        }
        nodes.push(node);
    }
    let root = nodes.len();
    nodes.push(json!({ "name": name, "children": (0..root).collect::<Vec<_>>() }));

    let animation = bone_animation(&mut buffer, poses, dt, first_bone);
    let mut document = json!({
        "asset": { "version": "2.0", "generator": "sinew bake (MSXPBD muscle simulation)" },
        "scene": 0,
        "scenes": [{ "name": name, "nodes": [root] }],
        "nodes": nodes,
        "meshes": meshes,
        "materials": [
            {
                "name": "muscle",
                "pbrMetallicRoughness": {
                    "baseColorFactor": [0.62, 0.16, 0.14, 1.0],
                    "metallicFactor": 0.0,
                    "roughnessFactor": 0.5,
                },
            },
            {
                "name": "bone",
                "pbrMetallicRoughness": {
                    "baseColorFactor": [0.90, 0.87, 0.78, 1.0],
                    "metallicFactor": 0.0,
                    "roughnessFactor": 0.7,
                },
            },
        ],
        "buffers": [{ "byteLength": buffer.bytes.len() }],
        "bufferViews": buffer.views,
        "accessors": buffer.accessors,
    });
    if let Some(animation) = animation {
        document["animations"] = json!([animation]);
    }
    assemble(&document, buffer.bytes)
}

/// One animation with a translation, rotation and scale channel for every
/// bone whose pose changes over `poses`; `None` when none does.
fn bone_animation(
    buffer: &mut BinaryBuffer,
    poses: &[Vec<Affine3A>],
    dt: f32,
    first_bone_node: usize,
) -> Option<Value> {
    let bone_count = poses.first().map_or(0, Vec::len);
    let moving: Vec<usize> = (0..bone_count)
        .filter(|&b| poses.iter().any(|frame| frame[b] != poses[0][b]))
        .collect();
    if moving.is_empty() || poses.len() < 2 {
        return None;
    }
    let times: Vec<f32> = (0..poses.len()).map(|k| k as f32 * dt).collect();
    let last = times[times.len() - 1];
    let input = buffer.accessor(
        floats(times.iter().copied()),
        None,
        FLOAT,
        times.len(),
        "SCALAR",
        Some((vec![0.0], vec![last])),
    );
    let mut samplers = Vec::new();
    let mut channels = Vec::new();
    for b in moving {
        let mut translations = Vec::with_capacity(poses.len());
        let mut rotations: Vec<Quat> = Vec::with_capacity(poses.len());
        let mut scales = Vec::with_capacity(poses.len());
        for frame in poses {
            let (s, mut r, t) = frame[b].to_scale_rotation_translation();
            // Keep consecutive keys in one hemisphere so that interpolation
            // takes the short way.
            if rotations.last().is_some_and(|prev| prev.dot(r) < 0.0) {
                r = -r;
            }
            translations.push(t);
            rotations.push(r);
            scales.push(s);
        }
        let node = first_bone_node + b;
        for (path, values, kind) in [
            ("translation", vec3_floats(&translations), "VEC3"),
            (
                "rotation",
                floats(rotations.iter().flat_map(|q| q.to_array())),
                "VEC4",
            ),
            ("scale", vec3_floats(&scales), "VEC3"),
        ] {
            let output = buffer.accessor(values, None, FLOAT, poses.len(), kind, None);
            samplers.push(json!({ "input": input, "output": output, "interpolation": "LINEAR" }));
            channels.push(json!({
                "sampler": samplers.len() - 1,
                "target": { "node": node, "path": path },
            }));
        }
    }
    Some(json!({ "name": "bake", "channels": channels, "samplers": samplers }))
}

fn vec3_floats(values: &[Vec3]) -> Vec<u8> {
    floats(values.iter().flat_map(|v| v.to_array()))
}
