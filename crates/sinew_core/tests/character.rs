//! Skinned characters: linear-blend skinning, the elbow-flexion clip, the
//! MakeHuman converter on a miniature MakeHuman folder (its bad inputs
//! included), and the `.glb` writer read back byte by byte.

use sinew_core::MeshError;
use sinew_core::character::makehuman::{self, MakeHumanOptions};
use sinew_core::character::primitives::two_bone_arm;
use sinew_core::character::{CharacterError, SkinnedCharacter, glb};
use sinew_core::glam::{Quat, Vec3};
use std::path::{Path, PathBuf};

#[test]
fn skinning_moves_the_forearm_about_the_elbow_and_keeps_the_upper_arm() {
    let arm = two_bone_arm(0.3, 0.04, 1.5);
    arm.validate().unwrap();
    let bind = arm.pose(&vec![Quat::IDENTITY; arm.joints.len()]);
    for (a, b) in arm.skin(&bind).iter().zip(&arm.positions) {
        assert!(
            (*a - *b).length() < 1e-6,
            "bind pose moved a vertex: {a} vs {b}"
        );
    }
    let clip = &arm.clips[0];
    assert_eq!(clip.duration(), 2.0);
    let peak = arm.pose(&clip.rotations_at(arm.joints.len(), 1.0));
    let skinned = arm.skin(&peak);
    let elbow = Vec3::new(0.0, -0.3, 0.0);
    for ((p, q), influences) in arm.positions.iter().zip(&skinned).zip(&arm.influences) {
        let upper = influences[0].1;
        if upper == 1.0 {
            assert!(
                (*p - *q).length() < 1e-6,
                "upper-arm vertex {p} moved to {q}"
            );
        } else if upper == 0.0 {
            // A forearm vertex keeps its distance to the elbow and turns 1.5 rad
            // about the hinge (the X axis).
            let (from, to) = (*p - elbow, *q - elbow);
            assert!((from.length() - to.length()).abs() < 1e-5);
            assert!((from.x - to.x).abs() < 1e-6, "the hinge is the X axis");
            if from.y < -0.1 {
                let (from, to) = (from.with_x(0.0), to.with_x(0.0));
                let turned = from.normalize().dot(to.normalize()).acos();
                assert!((turned - 1.5).abs() < 0.05, "turned {turned} rad");
            }
        }
    }
    let hand = skinned[arm.positions.len() - 1];
    assert!(hand.z > 0.25, "the hand flexes forward (+Z): {hand}");
}

#[test]
fn glb_holds_the_character_exactly_and_deterministically() {
    let arm = two_bone_arm(0.3, 0.04, 1.5);
    let bytes = glb::to_bytes(&arm).unwrap();
    assert_eq!(
        bytes,
        glb::to_bytes(&arm).unwrap(),
        "same character, same bytes"
    );
    assert_eq!(&bytes[0..4], b"glTF");
    assert_eq!(u32_at(&bytes, 4), 2);
    assert_eq!(u32_at(&bytes, 8) as usize, bytes.len());
    let json_len = u32_at(&bytes, 12) as usize;
    assert_eq!(&bytes[16..20], b"JSON");
    let doc: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let bin_at = 20 + json_len;
    assert_eq!(&bytes[bin_at + 4..bin_at + 8], b"BIN\0");
    let bin = &bytes[bin_at + 8..];

    let primitive = &doc["meshes"][0]["primitives"][0];
    let read = |accessor: &serde_json::Value| -> Vec<f32> {
        let a = &doc["accessors"][accessor.as_u64().unwrap() as usize];
        let view = &doc["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
        let offset = view["byteOffset"].as_u64().unwrap() as usize;
        let len = view["byteLength"].as_u64().unwrap() as usize;
        assert_eq!(offset % 4, 0, "views are 4-byte aligned");
        bin[offset..offset + len]
            .chunks(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect()
    };
    let positions = read(&primitive["attributes"]["POSITION"]);
    let expected: Vec<f32> = arm.positions.iter().flat_map(|p| p.to_array()).collect();
    assert_eq!(positions, expected);
    let weights = read(&primitive["attributes"]["WEIGHTS_0"]);
    for w in weights.chunks(4) {
        assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6);
    }
    let skin = &doc["skins"][0];
    assert_eq!(skin["joints"].as_array().unwrap().len(), arm.joints.len());
    let inverse_binds = read(&skin["inverseBindMatrices"]);
    // The forearm's inverse bind matrix takes the elbow to the origin.
    assert_eq!(&inverse_binds[2 * 16 + 12..2 * 16 + 15], &[0.0, 0.3, 0.0]);
    let animation = &doc["animations"][0];
    assert_eq!(animation["name"], "elbow_flex");
    let channel = &animation["channels"][0];
    assert_eq!(
        doc["nodes"][channel["target"]["node"].as_u64().unwrap() as usize]["name"],
        "forearm"
    );
    let sampler = &animation["samplers"][0];
    let times = read(&sampler["input"]);
    assert_eq!(times, arm.clips[0].channels[0].times);
}

#[test]
fn makehuman_folder_becomes_a_skinned_character() {
    let dir = mini_makehuman("ok", RIG, WEIGHTS);
    let character = makehuman::import(&dir, &test_rig()).unwrap();
    // The body group only: 4 vertices of the tetrahedron, 4 triangles, outward.
    assert_eq!(character.positions.len(), 4);
    assert_eq!(character.triangles.len(), 4);
    // Decimetres to metres, stood on y = 0 (the lowest body vertex was at -2 dm).
    let lowest = character
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f32::INFINITY, f32::min);
    assert_eq!(lowest, 0.0);
    // Root at the mean of its listed vertices, pelvis at its cube's mean.
    let root = &character.joints[character.joint("Root").unwrap()];
    assert!(
        (root.origin - Vec3::new(0.0, 0.0, 0.05)).length() < 1e-6,
        "{}",
        root.origin
    );
    let pelvis = &character.joints[character.joint("pelvis").unwrap()];
    assert!(
        (pelvis.origin - Vec3::new(0.0, 0.3, 0.0)).length() < 1e-6,
        "{}",
        pelvis.origin
    );
    assert_eq!(pelvis.parent, character.joint("Root"));
    // Vertex 0 had five influences: the strongest four, normalised.
    let v0 = character.influences[0];
    assert!(v0.iter().all(|(_, w)| *w > 0.0));
    assert!((v0.iter().map(|(_, w)| w).sum::<f32>() - 1.0).abs() < 1e-6);
    assert!(
        !v0.iter()
            .any(|(j, _)| character.joints[*j as usize].name == "spine_01")
    );
    // Not a game-engine rig: no clip; the .glb writes.
    glb::to_bytes(&character).unwrap();
}

#[test]
fn makehuman_bad_inputs_name_the_file_and_the_element() {
    let missing = makehuman::import(Path::new("/nonexistent/mh"), &MakeHumanOptions::default());
    assert!(
        matches!(&missing, Err(CharacterError::Mesh(MeshError::Io { file, .. })) if file.ends_with("3dobjs/base.obj")),
        "{missing:?}"
    );
    let cases = [
        ("json", "{ not json", WEIGHTS, "rig.test.json: the file"),
        (
            "parent",
            &RIG.replace("\"parent\": \"Root\"", "\"parent\": \"hips\""),
            WEIGHTS,
            "joint pelvis: parent 'hips'",
        ),
        (
            "cube",
            &RIG.replace("joint-pelvis", "joint-nowhere"),
            WEIGHTS,
            "no faces in group 'joint-nowhere'",
        ),
        (
            "strategy",
            &RIG.replace("\"MEAN\"", "\"VERTEX\""),
            WEIGHTS,
            "joint Root: head strategy Some(\"VERTEX\")",
        ),
        (
            "wjoint",
            RIG,
            &WEIGHTS.replace("\"spine_01\"", "\"spine_09\""),
            "weights of spine_09: no such joint",
        ),
        (
            "wvalue",
            RIG,
            &WEIGHTS.replace("[3, 1.0]", "[3, -1.0]"),
            "weights of pelvis: [3,-1.0] is not",
        ),
        (
            "wvertex",
            RIG,
            &WEIGHTS.replace("[3, 1.0]", "[99, 1.0]"),
            "vertex 99 past the mesh's",
        ),
        (
            "unweighted",
            RIG,
            &WEIGHTS.replace("[3, 1.0]", "[3, 0.0]"),
            "skin vertex 3: no joint weighs it",
        ),
    ];
    for (name, rig, weights, expected) in cases {
        let dir = mini_makehuman(name, rig, weights);
        let error = makehuman::import(&dir, &test_rig()).unwrap_err();
        let text = error.to_string();
        assert!(text.contains(expected), "{name}: {text}");
    }
}

#[test]
fn invalid_characters_are_refused_before_writing() {
    let mut arm = two_bone_arm(0.3, 0.04, 1.5);
    arm.influences[5][0].1 = 0.7;
    let error = glb::to_bytes(&arm).unwrap_err().to_string();
    assert!(error.contains("vertex 5"), "{error}");
    let mut arm = two_bone_arm(0.3, 0.04, 1.5);
    arm.joints[1].parent = Some(3);
    let error = glb::to_bytes(&arm).unwrap_err().to_string();
    assert!(
        error.contains("joint upper_arm: its parent comes after it"),
        "{error}"
    );
    let arm: SkinnedCharacter = two_bone_arm(0.3, 0.04, 1.5);
    let unwritable = glb::write(&arm, Path::new("/nonexistent/dir/arm.glb")).unwrap_err();
    assert!(
        unwritable.to_string().contains("/nonexistent/dir/arm.glb"),
        "{unwritable}"
    );
}

fn test_rig() -> MakeHumanOptions {
    MakeHumanOptions {
        rig: "test".into(),
        ..MakeHumanOptions::default()
    }
}

fn u32_at(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
}

/// A MakeHuman folder in miniature (decimetres, as MakeHuman): a body
/// tetrahedron (vertices 0–3), a helper triangle, and a pelvis marker cube
/// (here a quad whose mean is (0, 1, 0)).
fn mini_makehuman(name: &str, rig: &str, weights: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("sinew_mh_{name}_{}", std::process::id()));
    std::fs::create_dir_all(dir.join("3dobjs")).unwrap();
    std::fs::create_dir_all(dir.join("rigs/standard")).unwrap();
    let obj = "\
v 0 -2 0\nv 1 -2 0\nv 0 -2 1\nv 0 1 0\n\
v 5 5 5\nv 6 5 5\nv 5 6 5\n\
v -1 1 -1\nv 1 1 -1\nv 1 1 1\nv -1 1 1\n\
g body\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n\
g helper-hair\nf 5 6 7\n\
g joint-pelvis\nf 8 9 10 11\n";
    std::fs::write(dir.join("3dobjs/base.obj"), obj).unwrap();
    std::fs::write(dir.join("rigs/standard/rig.test.json"), rig).unwrap();
    std::fs::write(dir.join("rigs/standard/weights.test.json"), weights).unwrap();
    dir
}

const RIG: &str = r#"{
  "Root": { "parent": "", "head": { "strategy": "MEAN", "vertex_indices": [0, 2] } },
  "pelvis": { "parent": "Root", "head": { "strategy": "CUBE", "cube_name": "joint-pelvis" } },
  "spine_01": { "parent": "pelvis", "head": { "strategy": "CUBE", "cube_name": "joint-pelvis" } },
  "thigh_l": { "parent": "pelvis", "head": { "strategy": "CUBE", "cube_name": "joint-pelvis" } },
  "thigh_r": { "parent": "pelvis", "head": { "strategy": "CUBE", "cube_name": "joint-pelvis" } }
}"#;

const WEIGHTS: &str = r#"{ "weights": {
  "Root": [[0, 0.4], [1, 1.0], [2, 1.0]],
  "pelvis": [[0, 0.3], [3, 1.0]],
  "spine_01": [[0, 0.05]],
  "thigh_l": [[0, 0.2], [4, 1.0]],
  "thigh_r": [[0, 0.1]]
} }"#;
