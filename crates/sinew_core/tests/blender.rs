//! Blender, a real DCC, reads sinew's skinned glTF: it imports the `.glb`,
//! poses it along its clip, and its skinned mesh equals glTF's linear-blend
//! skinning of the file to 1e-5 m (`scripts/blender/check_glb.py`). Skipped,
//! with a message, where `blender` is not on the PATH (Debian: `apt-get
//! install blender python3-numpy`); `.ci/run` installs it.

use sinew_core::character::{glb, primitives::two_bone_arm};
use std::path::{Path, PathBuf};
use std::process::Command;

fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Runs the Blender check on `file` at key times `times` (s), also against
/// sinew's skinning in `expected` when given; `None` when Blender is absent.
fn blender_check(file: &Path, times: &[&str], expected: Option<&Path>) -> Option<(bool, String)> {
    let script = repository().join("scripts/blender/check_glb.py");
    let mut command = Command::new("blender");
    if let Some(dir) = expected {
        command.env("SINEW_EXPECTED", dir);
    }
    let output = command
        .args(["-b", "--factory-startup", "--python"])
        .arg(&script)
        .arg("--")
        .arg(file)
        .args(times)
        .output()
        .ok()?;
    let text = String::from_utf8_lossy(&output.stdout).into_owned()
        + &String::from_utf8_lossy(&output.stderr);
    let results = text.lines().filter(|l| l.starts_with("RESULT")).count();
    let per_time = if expected.is_some() { 2 } else { 1 };
    Some((
        output.status.success() && results == per_time * times.len(),
        text,
    ))
}

#[test]
fn blender_skins_sinew_characters_as_gltf_defines() {
    let dir = std::env::temp_dir().join(format!("sinew_blender_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let arm = dir.join("arm.glb");
    let character = two_bone_arm(0.3, 0.04, 1.5);
    glb::write(&character, &arm).unwrap();
    // sinew's own skinning along the clip, for Blender to match.
    let times = ["0", "0.5", "1"];
    for t in times {
        let rotations = character.clips[0].rotations_at(character.joints.len(), t.parse().unwrap());
        let skinned = character.skin(&character.pose(&rotations));
        let bytes: Vec<u8> = skinned
            .iter()
            .flat_map(|p| p.to_array())
            .flat_map(f32::to_le_bytes)
            .collect();
        std::fs::write(dir.join(format!("{t}.f32")), bytes).unwrap();
    }
    let makehuman = repository().join("assets/characters/makehuman.glb");
    for (file, expected) in [(&arm, Some(dir.as_path())), (&makehuman, None)] {
        let Some((ok, text)) = blender_check(file, &times, expected) else {
            eprintln!(
                "skipped: `blender` is not on the PATH (apt-get install blender python3-numpy)"
            );
            return;
        };
        for line in text.lines().filter(|l| l.starts_with("RESULT")) {
            eprintln!("{}: {line}", file.display());
        }
        assert!(ok, "Blender disagrees on {}:\n{text}", file.display());
    }
}
