//! Reading a skinned glTF (`.glb`) into a [`SkinnedCharacter`]: the first
//! node with a skinned mesh, its skin's joints (parents before children),
//! positions, triangles, `JOINTS_0`/`WEIGHTS_0`, and the rotation channels
//! of its joints' animations. What the model cannot hold is reported, never
//! dropped silently: [`GlbCharacter::skipped`] lists animation channels not
//! read (translation, scale, cubic splines), and joints rotated at the bind
//! pose are refused with an error that says so (sinew's characters bind
//! axis-aligned joints, as its MakeHuman converter writes them).

use super::{CharacterError, JointClip, MAX_INFLUENCES, RotationChannel, SkinnedCharacter};
use crate::character::Joint;
use crate::glb_container::GlbDocument;
use glam::{Mat3, Mat4, Quat, Vec3};
use serde_json::Value;
use std::path::Path;

/// A character read from a `.glb`, with what was left out.
#[derive(Clone, Debug, PartialEq)]
pub struct GlbCharacter {
    /// The character.
    pub character: SkinnedCharacter,
    /// Parts of the file the character does not hold, one line each (e.g.
    /// "animation 'walk': 1 translation channel not read").
    pub skipped: Vec<String>,
}

/// Reads the skinned character of `path`. Errors name the file and the
/// element: no skinned mesh, a broken container or accessor, a joint
/// rotated at the bind pose, weights that do not add up.
pub fn read(path: &Path) -> Result<GlbCharacter, CharacterError> {
    let bytes = std::fs::read(path).map_err(|source| CharacterError::Io {
        file: path.to_path_buf(),
        source,
    })?;
    let fail = |element: &str, reason: String| CharacterError::Json {
        file: path.to_path_buf(),
        element: element.to_string(),
        reason,
    };
    let doc = GlbDocument::parse(&bytes).map_err(|r| fail("container", r))?;
    let json = &doc.json;
    let empty = Vec::new();
    let nodes = json["nodes"].as_array().unwrap_or(&empty);
    let (node_index, node) = nodes
        .iter()
        .enumerate()
        .find(|(_, n)| n.get("mesh").is_some() && n.get("skin").is_some())
        .ok_or_else(|| {
            fail(
                "skin",
                "no node has a skinned mesh (a mesh with a skin)".into(),
            )
        })?;
    let mesh = &json["meshes"][node["mesh"].as_u64().unwrap_or(0) as usize];
    let skin = &json["skins"][node["skin"].as_u64().unwrap_or(0) as usize];

    // Joints, parents before children.
    let joint_nodes: Vec<usize> = skin["joints"]
        .as_array()
        .ok_or_else(|| fail("skin", "it lists no joints".into()))?
        .iter()
        .map(|j| j.as_u64().unwrap_or(u64::MAX) as usize)
        .collect();
    let mut node_parent = vec![None; nodes.len()];
    for (p, n) in nodes.iter().enumerate() {
        for c in n["children"].as_array().unwrap_or(&empty) {
            if let Some(slot) = node_parent.get_mut(c.as_u64().unwrap_or(u64::MAX) as usize) {
                *slot = Some(p);
            }
        }
    }
    let joint_parent = |k: usize| {
        let mut at = node_parent.get(joint_nodes[k]).copied().flatten();
        let mut steps = 0;
        while let Some(n) = at {
            if let Some(j) = joint_nodes.iter().position(|&jn| jn == n) {
                return Some(j);
            }
            at = node_parent[n];
            steps += 1;
            if steps > nodes.len() {
                break;
            }
        }
        None
    };
    let depth = |k: usize| {
        let (mut d, mut at) = (0, joint_parent(k));
        while let Some(p) = at.filter(|_| d <= joint_nodes.len()) {
            d += 1;
            at = joint_parent(p);
        }
        d
    };
    // The skin's order when it lists parents first (sinew's own files, most
    // exporters); else by depth in the hierarchy.
    let mut order: Vec<usize> = (0..joint_nodes.len()).collect();
    if (0..joint_nodes.len()).any(|k| joint_parent(k).is_some_and(|p| p > k)) {
        order.sort_by_key(|&k| depth(k));
    }
    let mut new_index = vec![0usize; joint_nodes.len()];
    for (new, &old) in order.iter().enumerate() {
        new_index[old] = new;
    }
    let inverse_binds = match skin.get("inverseBindMatrices").and_then(Value::as_u64) {
        Some(a) => doc
            .accessor(a as usize, 16)
            .map_err(|r| fail("skin inverse bind matrices", r))?,
        None => Mat4::IDENTITY
            .to_cols_array()
            .iter()
            .map(|&x| x as f64)
            .cycle()
            .take(16 * joint_nodes.len())
            .collect(),
    };
    let mut joints = Vec::with_capacity(joint_nodes.len());
    let mut rest_rotation = Vec::with_capacity(joint_nodes.len());
    for &old in &order {
        let n = &nodes[joint_nodes[old]];
        let name = n["name"]
            .as_str()
            .map_or_else(|| format!("joint_{}", joint_nodes[old]), str::to_string);
        let m: Vec<f32> = inverse_binds[16 * old..16 * old + 16]
            .iter()
            .map(|&x| x as f32)
            .collect();
        let inverse_bind = Mat4::from_cols_slice(&m);
        let rotation = Mat3::from_mat4(inverse_bind);
        let origin = if rotation == Mat3::IDENTITY {
            -inverse_bind.w_axis.truncate()
        } else {
            let bind = inverse_bind.inverse();
            if !Mat3::from_mat4(bind).abs_diff_eq(Mat3::IDENTITY, 1e-4) {
                return Err(fail(
                    &format!("joint {name}"),
                    "rotated at the bind pose: sinew's characters bind axis-aligned joints".into(),
                ));
            }
            bind.w_axis.truncate()
        };
        joints.push(Joint {
            name,
            parent: joint_parent(old).map(|p| new_index[p]),
            origin,
        });
        rest_rotation.push(quat(n.get("rotation")).unwrap_or(Quat::IDENTITY));
    }

    // Skin mesh: every triangle primitive, merged.
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    let mut influences = Vec::new();
    for (k, primitive) in mesh["primitives"]
        .as_array()
        .unwrap_or(&empty)
        .iter()
        .enumerate()
    {
        let element = format!("mesh primitive {k}");
        if primitive["mode"].as_u64().unwrap_or(4) != 4 {
            return Err(fail(&element, "not triangles (mode 4)".into()));
        }
        let attribute = |name: &str, width: usize| {
            let a = primitive["attributes"][name]
                .as_u64()
                .ok_or_else(|| fail(&element, format!("no {name}")))?;
            doc.accessor(a as usize, width)
                .map_err(|r| fail(&element, r))
        };
        let first = positions.len() as u32;
        let p = attribute("POSITION", 3)?;
        let j = attribute("JOINTS_0", 4)?;
        let w = attribute("WEIGHTS_0", 4)?;
        let count = p.len() / 3;
        if j.len() / 4 != count || w.len() / 4 != count {
            return Err(fail(&element, "attribute counts differ".into()));
        }
        positions.extend(
            p.chunks_exact(3)
                .map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32)),
        );
        for (v, (jv, wv)) in j.chunks_exact(4).zip(w.chunks_exact(4)).enumerate() {
            let sum: f64 = wv.iter().sum();
            if sum.is_nan() || sum <= 0.0 {
                return Err(fail(&element, format!("vertex {v} has no weight")));
            }
            let mut slots = [(0u16, 0.0f32); MAX_INFLUENCES];
            for s in 0..MAX_INFLUENCES {
                let joint = jv[s] as usize;
                if wv[s] > 0.0 && joint >= joint_nodes.len() {
                    return Err(fail(&element, format!("vertex {v} names joint {joint}")));
                }
                // Weights that already sum to 1 (to f32's precision) are kept bit
                // for bit; others are normalised.
                let weight = if (sum - 1.0).abs() <= 1e-5 {
                    wv[s] as f32
                } else {
                    (wv[s] / sum) as f32
                };
                slots[s] = (new_index.get(joint).copied().unwrap_or(0) as u16, weight);
            }
            influences.push(slots);
        }
        let indices: Vec<u32> = match primitive["indices"].as_u64() {
            Some(a) => doc
                .accessor(a as usize, 1)
                .map_err(|r| fail(&element, r))?
                .iter()
                .map(|&i| first + i as u32)
                .collect(),
            None => (first..first + count as u32).collect(),
        };
        triangles.extend(indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]));
    }

    // Rotation channels of the joints, as rotations from the bind pose.
    let mut clips = Vec::new();
    let mut skipped = Vec::new();
    for (a, animation) in json["animations"]
        .as_array()
        .unwrap_or(&empty)
        .iter()
        .enumerate()
    {
        let name = animation["name"]
            .as_str()
            .map_or_else(|| format!("animation_{a}"), str::to_string);
        let mut channels = Vec::new();
        let mut not_read = std::collections::BTreeMap::<String, usize>::new();
        for channel in animation["channels"].as_array().unwrap_or(&empty) {
            let target = channel["target"]["node"].as_u64().unwrap_or(u64::MAX) as usize;
            let path = channel["target"]["path"].as_str().unwrap_or("");
            let sampler = &animation["samplers"][channel["sampler"].as_u64().unwrap_or(0) as usize];
            let interpolation = sampler["interpolation"].as_str().unwrap_or("LINEAR");
            let joint = joint_nodes.iter().position(|&n| n == target);
            let (Some(joint), "rotation", "LINEAR" | "STEP") = (joint, path, interpolation) else {
                let what = match joint {
                    None => format!("{path} channel on a node outside the skin"),
                    Some(_) if path != "rotation" => format!("{path} channel"),
                    Some(_) => format!("{interpolation} rotation channel"),
                };
                *not_read.entry(what).or_default() += 1;
                continue;
            };
            let element = format!("animation '{name}'");
            let times: Vec<f32> = doc
                .accessor(sampler["input"].as_u64().unwrap_or(u64::MAX) as usize, 1)
                .map_err(|r| fail(&element, r))?
                .iter()
                .map(|&t| t as f32)
                .collect();
            let rest = rest_rotation[new_index[joint]].inverse();
            let rotations: Vec<Quat> = doc
                .accessor(sampler["output"].as_u64().unwrap_or(u64::MAX) as usize, 4)
                .map_err(|r| fail(&element, r))?
                .chunks_exact(4)
                .map(|q| {
                    let q = Quat::from_xyzw(q[0] as f32, q[1] as f32, q[2] as f32, q[3] as f32);
                    if rest == Quat::IDENTITY { q } else { rest * q }
                })
                .collect();
            channels.push(RotationChannel {
                joint: new_index[joint],
                times,
                rotations,
            });
        }
        for (what, count) in not_read {
            skipped.push(format!("animation '{name}': {count} {what}(s) not read"));
        }
        if channels.is_empty() {
            skipped.push(format!(
                "animation '{name}': no rotation of a joint, not read"
            ));
        } else {
            clips.push(JointClip { name, channels });
        }
    }
    let extra = nodes
        .iter()
        .enumerate()
        .filter(|&(i, n)| i != node_index && n.get("mesh").is_some())
        .count();
    if extra > 0 {
        skipped.push(format!(
            "{extra} other mesh node(s) not read (only the first skinned mesh)"
        ));
    }
    let name = json["scenes"][0]["name"]
        .as_str()
        .map(str::to_string)
        .or_else(|| path.file_stem().map(|s| s.to_string_lossy().into_owned()))
        .unwrap_or_default();
    let character = SkinnedCharacter {
        name,
        positions,
        triangles,
        joints,
        influences,
        clips,
    };
    character.validate()?;
    Ok(GlbCharacter { character, skipped })
}

/// A glTF quaternion `[x, y, z, w]`, if `value` is one.
fn quat(value: Option<&Value>) -> Option<Quat> {
    let q = value?.as_array()?;
    let c = |i: usize| q.get(i).and_then(Value::as_f64).map(|x| x as f32);
    Some(Quat::from_xyzw(c(0)?, c(1)?, c(2)?, c(3)?))
}
