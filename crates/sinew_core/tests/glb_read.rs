//! Reading skinned glTF characters back: sinew's own `.glb`s read into the
//! same character (written again, the same bytes), and bad files refused
//! with the file and the element named.

use sinew_core::bake::{Bake, BakeFormat};
use sinew_core::character::primitives::two_bone_arm;
use sinew_core::character::{CharacterError, glb};
use sinew_core::scene::builtin;
use std::path::{Path, PathBuf};

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("sinew_glb_read_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn a_written_character_reads_back_the_same() {
    let arm = two_bone_arm(0.3, 0.04, 1.5);
    let file = scratch("arm.glb");
    glb::write(&arm, &file).unwrap();
    let read = glb::read(&file).unwrap();
    assert_eq!(read.character, arm);
    assert!(read.skipped.is_empty(), "{:?}", read.skipped);
}

#[test]
fn the_makehuman_character_reads_and_writes_back_byte_for_byte() {
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/characters/makehuman.glb");
    let read = glb::read(&file).unwrap();
    let c = &read.character;
    assert_eq!(
        (c.positions.len(), c.triangles.len(), c.joints.len()),
        (13_380, 26_756, 53)
    );
    let clips: Vec<&str> = c.clips.iter().map(|clip| clip.name.as_str()).collect();
    assert_eq!(clips, ["elbow_flex", "walk"]);
    let (written, original) = (glb::to_bytes(c).unwrap(), std::fs::read(&file).unwrap());
    let first_difference = written.iter().zip(&original).position(|(a, b)| a != b);
    assert!(
        written.len() == original.len() && first_difference.is_none(),
        "{} vs {} bytes, first difference at {first_difference:?}",
        written.len(),
        original.len()
    );
}

#[test]
fn bad_files_are_refused_with_the_file_and_the_element() {
    let reason = |file: &Path| match glb::read(file) {
        Err(e @ (CharacterError::Json { .. } | CharacterError::Io { .. })) => {
            let text = e.to_string();
            assert!(text.contains(&file.display().to_string()), "{text}");
            text
        }
        other => panic!(
            "{}: expected an error naming it, got {other:?}",
            file.display()
        ),
    };
    // Missing, not a glb, truncated.
    assert!(reason(&scratch("missing.glb")).contains("No such file"));
    let text = scratch("text.glb");
    std::fs::write(&text, "solid cube").unwrap();
    assert!(reason(&text).contains("magic"));
    let arm = glb::to_bytes(&two_bone_arm(0.3, 0.04, 1.5)).unwrap();
    let truncated = scratch("truncated.glb");
    std::fs::write(&truncated, &arm[..arm.len() / 2]).unwrap();
    assert!(reason(&truncated).contains("runs past"));
    // A glTF with meshes but no skin: a bake's scene.
    let solver = builtin("P1").unwrap().instantiate(Path::new(".")).unwrap();
    let bake = Bake::start(&solver, &scratch("bake"), &[BakeFormat::Glb]).unwrap();
    let no_skin = bake.finish().unwrap().remove(0);
    assert!(reason(&no_skin).contains("no node has a skinned mesh"));
    // A joint rotated at the bind pose: turn the first inverse bind matrix.
    let len = u32::from_le_bytes(arm[12..16].try_into().unwrap()) as usize;
    let doc: serde_json::Value = serde_json::from_slice(&arm[20..20 + len]).unwrap();
    let accessor = doc["skins"][0]["inverseBindMatrices"].as_u64().unwrap() as usize;
    let view = doc["accessors"][accessor]["bufferView"].as_u64().unwrap() as usize;
    let at = 20 + len + 8 + doc["bufferViews"][view]["byteOffset"].as_u64().unwrap() as usize;
    let mut rotated = arm.clone();
    // Columns 0 and 1 of a 90° turn about Z.
    for (k, value) in [0.0f32, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0]
        .iter()
        .enumerate()
    {
        rotated[at + 4 * k..at + 4 * k + 4].copy_from_slice(&value.to_le_bytes());
    }
    let file = scratch("rotated.glb");
    std::fs::write(&file, rotated).unwrap();
    let text = reason(&file);
    assert!(
        text.contains("joint shoulder") && text.contains("rotated at the bind pose"),
        "{text}"
    );
}
