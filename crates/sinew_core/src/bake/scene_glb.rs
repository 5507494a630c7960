//! The bake's `.glb`: every muscle's surface at the first baked frame, the
//! skeleton's bodies as a node hierarchy, and every bone (its mesh, if it has
//! one) under the body it follows, their poses animated over the bake, in
//! metres. The muscles' motion is in their `.pc2` caches, whose file names
//! the muscle nodes carry in their `extras` (`"sinew_pc2"`); `extras` also
//! give each node's index among the solver's muscles (`"sinew_muscle"`),
//! skeleton bodies (`"sinew_body"`) or bones (`"sinew_bone"`), for tools that
//! match them by position in a list.

use crate::glb_container::{BinaryBuffer, FLOAT, assemble, floats};
use crate::solver::Solver;
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

/// A skeleton body or a bone as written: a node under `parent` (an earlier
/// node; `None`: the scene's root) with its mesh in its own frame (metres),
/// if any.
#[derive(Clone, Debug)]
pub(super) struct NodeRecord {
    pub name: String,
    pub parent: Option<usize>,
    pub mesh: Option<MeshRecord>,
    pub extras: Value,
}

/// The skeleton's bodies (in the rig's order) then the bones, each bone
/// under the body it follows.
pub(super) fn nodes(solver: &Solver, unit: f32) -> Vec<NodeRecord> {
    let mut nodes: Vec<NodeRecord> = solver.skeleton().map_or_else(Vec::new, |rig| {
        (0..rig.body_count())
            .map(|b| NodeRecord {
                name: rig.body_names()[b].clone(),
                parent: rig.parent(b),
                mesh: None,
                extras: json!({ "sinew_body": b }),
            })
            .collect()
    });
    let bodies = nodes.len();
    for (b, bone) in solver.bones().iter().enumerate() {
        let mesh = bone.target.map(|t| {
            let target = &solver.targets()[t];
            MeshRecord {
                name: bone.name.clone(),
                positions: target.positions().iter().map(|&p| p / unit).collect(),
                triangles: target.triangles().to_vec(),
                cache: None,
            }
        });
        nodes.push(NodeRecord {
            name: bone.name.clone(),
            parent: bone.body.filter(|&body| body < bodies),
            mesh,
            extras: json!({ "sinew_bone": b }),
        });
    }
    nodes
}

/// Every node's pose in its parent's frame now (translations in metres), in
/// the order of [`nodes`]; `values` and `world` are scratch.
pub(super) fn local_poses(
    solver: &Solver,
    unit: f32,
    values: &mut Vec<f32>,
    world: &mut Vec<Affine3A>,
) -> Vec<Affine3A> {
    world.clear();
    if let Some(rig) = solver.skeleton() {
        rig.pose_at(solver.time(), values, world);
    }
    let in_metres = |mut pose: Affine3A| {
        pose.translation /= unit;
        pose
    };
    let bodies = world.len();
    let mut poses: Vec<Affine3A> = (0..bodies)
        .map(|b| {
            let parent = solver.skeleton().and_then(|rig| rig.parent(b));
            in_metres(parent.map_or(world[b], |p| world[p].inverse() * world[b]))
        })
        .collect();
    poses.extend(solver.bones().iter().map(|bone| {
        let body = bone.body.filter(|&b| b < bodies);
        in_metres(body.map_or(bone.transform, |b| world[b].inverse() * bone.transform))
    }));
    poses
}

/// Material indices of the document.
const MUSCLE_MATERIAL: usize = 0;
const BONE_MATERIAL: usize = 1;

/// The `.glb` bytes: `muscles` at rest, `nodes` posed by `poses` (per
/// frame, per node, in its parent's frame, translations in metres), frames
/// `dt` seconds apart.
pub(super) fn to_bytes(
    name: &str,
    muscles: &[MeshRecord],
    nodes: &[NodeRecord],
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

    let mut written: Vec<Value> = Vec::new();
    for (m, muscle) in muscles.iter().enumerate() {
        let mesh = mesh_of(&mut buffer, muscle, MUSCLE_MATERIAL);
        let mut node =
            json!({ "name": muscle.name, "mesh": mesh, "extras": { "sinew_muscle": m } });
        if let Some(cache) = &muscle.cache {
            node["extras"]["sinew_pc2"] = json!(cache);
        }
        written.push(node);
    }
    let first_node = written.len();
    for (k, record) in nodes.iter().enumerate() {
        let (scale, rotation, translation) = poses[0][k].to_scale_rotation_translation();
        let mut node = json!({
            "name": record.name,
            "translation": translation.to_array(),
            "rotation": rotation.to_array(),
            "extras": record.extras,
        });
        if !scale.abs_diff_eq(Vec3::ONE, 1e-6) {
            node["scale"] = json!(scale.to_array());
        }
        if let Some(mesh) = &record.mesh {
            node["mesh"] = json!(mesh_of(&mut buffer, mesh, BONE_MATERIAL));
        }
        let children: Vec<usize> = (0..nodes.len())
            .filter(|&c| nodes[c].parent == Some(k))
            .map(|c| first_node + c)
            .collect();
        if !children.is_empty() {
            node["children"] = json!(children);
        }
        written.push(node);
    }
    let root = written.len();
    let top: Vec<usize> = (0..first_node)
        .chain(
            (0..nodes.len())
                .filter(|&k| nodes[k].parent.is_none())
                .map(|k| first_node + k),
        )
        .collect();
    written.push(json!({ "name": name, "children": top }));

    let animation = node_animation(&mut buffer, poses, dt, first_node);
    let mut document = json!({
        "asset": { "version": "2.0", "generator": "sinew bake (MSXPBD muscle simulation)" },
        "scene": 0,
        "scenes": [{ "name": name, "nodes": [root] }],
        "nodes": written,
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
/// node whose pose changes over `poses`; `None` when none does.
fn node_animation(
    buffer: &mut BinaryBuffer,
    poses: &[Vec<Affine3A>],
    dt: f32,
    first_node: usize,
) -> Option<Value> {
    let node_count = poses.first().map_or(0, Vec::len);
    let moving: Vec<usize> = (0..node_count)
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
        let node = first_node + b;
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
