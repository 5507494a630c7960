//! A [`SkinnedCharacter`] as binary glTF 2.0 (`.glb`): one scene whose root
//! node holds the joint hierarchy and the skinned skin mesh (positions,
//! normals, `JOINTS_0`, `WEIGHTS_0`, one skin material), the skin's inverse
//! bind matrices, and one animation per clip (`LINEAR` rotation samplers).
//! The output is deterministic: the same character gives the same bytes.

pub use super::glb_read::{GlbCharacter, read};
use super::{CharacterError, SkinnedCharacter};
use crate::glb_container::{ARRAY_BUFFER, BinaryBuffer, FLOAT, UNSIGNED_SHORT, assemble, floats};
use glam::Mat4;
use serde_json::{Value, json};
use std::path::Path;

/// Writes `character` (validated first) to `path` as a `.glb`.
pub fn write(character: &SkinnedCharacter, path: &Path) -> Result<(), CharacterError> {
    let bytes = to_bytes(character)?;
    crate::atomic_file::write(path, bytes).map_err(|source| CharacterError::Io {
        file: path.to_path_buf(),
        source,
    })
}

/// `character` (validated first) as the bytes of a `.glb`.
pub fn to_bytes(character: &SkinnedCharacter) -> Result<Vec<u8>, CharacterError> {
    character.validate()?;
    let mut buffer = BinaryBuffer::default();
    let n = character.positions.len();

    let position = buffer.positions(&character.positions);
    let normal = buffer.normals(&character.triangles, &character.positions);
    let joint_bytes = character
        .influences
        .iter()
        .flatten()
        .flat_map(|(j, _)| j.to_le_bytes())
        .collect();
    let joints = buffer.accessor(
        joint_bytes,
        Some(ARRAY_BUFFER),
        UNSIGNED_SHORT,
        n,
        "VEC4",
        None,
    );
    let weights = buffer.accessor(
        floats(character.influences.iter().flatten().map(|(_, w)| *w)),
        Some(ARRAY_BUFFER),
        FLOAT,
        n,
        "VEC4",
        None,
    );
    let indices = buffer.indices(&character.triangles);
    let inverse_binds = buffer.accessor(
        floats(
            character
                .joints
                .iter()
                .flat_map(|j| Mat4::from_translation(-j.origin).to_cols_array()),
        ),
        None,
        FLOAT,
        character.joints.len(),
        "MAT4",
        None,
    );

    // Nodes: the joints (0..J, in the character's order), the skin mesh, the root.
    let joint_count = character.joints.len();
    let mut nodes: Vec<Value> = character
        .joints
        .iter()
        .enumerate()
        .map(|(k, joint)| {
            let children: Vec<usize> = character
                .joints
                .iter()
                .enumerate()
                .filter(|(_, j)| j.parent == Some(k))
                .map(|(c, _)| c)
                .collect();
            let mut node = json!({
                "name": joint.name,
                "translation": character.local_translation(k).to_array(),
            });
            if !children.is_empty() {
                node["children"] = json!(children);
            }
            node
        })
        .collect();
    let mesh_node = joint_count;
    let root_node = joint_count + 1;
    nodes.push(json!({ "name": format!("{}_skin", character.name), "mesh": 0, "skin": 0 }));
    let mut root_children: Vec<usize> = character
        .joints
        .iter()
        .enumerate()
        .filter(|(_, j)| j.parent.is_none())
        .map(|(k, _)| k)
        .collect();
    root_children.push(mesh_node);
    nodes.push(json!({ "name": character.name, "children": root_children }));

    let mut animations = Vec::new();
    for clip in &character.clips {
        let mut samplers = Vec::new();
        let mut channels = Vec::new();
        for (s, channel) in clip.channels.iter().enumerate() {
            let first = channel.times[0];
            let last = *channel.times.last().unwrap_or(&first);
            let input = buffer.accessor(
                floats(channel.times.iter().copied()),
                None,
                FLOAT,
                channel.times.len(),
                "SCALAR",
                Some((vec![first], vec![last])),
            );
            let output = buffer.accessor(
                floats(channel.rotations.iter().flat_map(|q| q.to_array())),
                None,
                FLOAT,
                channel.rotations.len(),
                "VEC4",
                None,
            );
            samplers.push(json!({ "input": input, "output": output, "interpolation": "LINEAR" }));
            channels.push(json!({
                "sampler": s,
                "target": { "node": channel.joint, "path": "rotation" },
            }));
        }
        animations.push(json!({ "name": clip.name, "channels": channels, "samplers": samplers }));
    }

    let roots: Vec<usize> = (0..joint_count)
        .filter(|&k| character.joints[k].parent.is_none())
        .collect();
    let mut skin = json!({
        "name": format!("{}_skeleton", character.name),
        "inverseBindMatrices": inverse_binds,
        "joints": (0..joint_count).collect::<Vec<_>>(),
    });
    if let [root] = roots[..] {
        skin["skeleton"] = json!(root);
    }
    let mut document = json!({
        "asset": { "version": "2.0", "generator": "sinew (MSXPBD muscle simulation)" },
        "scene": 0,
        "scenes": [{ "name": character.name, "nodes": [root_node] }],
        "nodes": nodes,
        "meshes": [{
            "name": format!("{}_skin", character.name),
            "primitives": [{
                "attributes": {
                    "POSITION": position,
                    "NORMAL": normal,
                    "JOINTS_0": joints,
                    "WEIGHTS_0": weights,
                },
                "indices": indices,
                "material": 0,
                "mode": 4,
            }],
        }],
        "materials": [{
            "name": "skin",
            "pbrMetallicRoughness": {
                "baseColorFactor": [0.80, 0.62, 0.52, 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 0.6,
            },
        }],
        "skins": [skin],
        "buffers": [{ "byteLength": buffer.bytes.len() }],
        "bufferViews": buffer.views,
        "accessors": buffer.accessors,
    });
    if !animations.is_empty() {
        document["animations"] = json!(animations);
    }
    Ok(assemble(&document, buffer.bytes))
}
