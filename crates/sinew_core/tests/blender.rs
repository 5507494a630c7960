//! Blender, a real DCC, reads what sinew writes:
//!
//! - a skinned glTF character: Blender imports the `.glb`, poses it along
//!   its clip, and its skinned mesh equals glTF's linear-blend skinning of
//!   the file and sinew's own to 1e-5 m (`scripts/blender/check_glb.py`);
//! - a bake (`sinew bake --format pc2,glb`): Blender imports the `.glb`,
//!   plays each muscle's `.pc2` with a Mesh Cache modifier and the bones'
//!   keys, and at frames 1, 60 and 120 every vertex equals sinew's to 1e-5 m
//!   (`scripts/blender/check_bake.py`).
//!
//! Skipped, with a message, where `blender` is not on the PATH (Debian:
//! `apt-get install blender python3-numpy`); `.ci/run` installs it.

use sinew_core::bake::{Bake, BakeFormat};
use sinew_core::character::fit::{FitOptions, RigMap, SkinLayer, fit_anatomy};
use sinew_core::character::{ClipPlayback, glb, primitives::two_bone_arm};
use sinew_core::scene::Scene;
use std::path::{Path, PathBuf};
use std::process::Command;

fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Runs the Blender check `script` (in `scripts/blender/`) on `file` at
/// `times` (key times in s, or frames), also against sinew's positions in
/// `expected` when given; `None` when Blender is absent.
fn blender_check(
    script: &str,
    file: &Path,
    times: &[&str],
    expected: Option<&Path>,
) -> Option<(bool, String)> {
    let script = repository().join("scripts/blender").join(script);
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
    Some((output.status.success() && results == times.len(), text))
}

#[test]
fn blender_skins_sinew_characters_as_gltf_defines() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("sinew_blender_{}", std::process::id()));
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
        let Some((ok, text)) = blender_check("check_glb.py", file, &times, expected) else {
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

#[test]
fn blender_plays_a_bake_as_sinew_simulated_it() {
    let path = repository().join("assets/scenes/t5.ron");
    let scene = Scene::load(&path).unwrap();
    let solver = scene.instantiate(path.parent().unwrap()).unwrap();
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("sinew_blender_bake_{}", std::process::id()));
    bake_and_check(solver, &dir, &["1", "60", "120"]);
}

/// The character's skin is one more cache: T7 fitted to MakeHuman with its
/// skin, walking; Blender plays the skin's `.pc2` and every muscle's as
/// sinew simulated them.
#[test]
fn blender_plays_the_characters_skin_as_sinew_simulated_it() {
    let character = glb::read(&repository().join("assets/characters/makehuman.glb"))
        .unwrap()
        .character;
    let path = repository().join("assets/scenes/t7.ron");
    let anatomy = Scene::load(&path).unwrap();
    let solver = anatomy.instantiate(path.parent().unwrap()).unwrap();
    let fitted = fit_anatomy(
        &character,
        &solver,
        &RigMap::game_engine(),
        &FitOptions::default(),
    )
    .unwrap();
    let walk = character.clips.iter().find(|c| c.name == "walk");
    let playback = ClipPlayback {
        lead_in: 0.5,
        until: 1.5,
    };
    let mut scene = fitted
        .fit
        .scene(
            &anatomy,
            &solver,
            &fitted.geometry,
            &character,
            walk,
            &playback,
        )
        .unwrap();
    scene.add_skin(&character, &SkinLayer::default());
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("sinew_blender_skin_{}", std::process::id()));
    let file = dir.join("scene/fitted.ron");
    scene.save(&file).unwrap();
    let built = scene.scene.instantiate(file.parent().unwrap()).unwrap();
    assert!(built.muscle_index("skin").is_some());
    bake_and_check(built, &dir, &["1", "30", "60"]);
}

/// Bakes `solver` (pc2 and glb) into `dir` up to the last of `frames`,
/// writes sinew's own positions at `frames`, and has Blender compare.
fn bake_and_check(mut solver: sinew_core::Solver, dir: &Path, frames: &[&str]) {
    let _ = std::fs::remove_dir_all(dir);
    let out = dir.join("bake");
    let expected = dir.join("expected");
    std::fs::create_dir_all(&expected).unwrap();
    let last: u32 = frames
        .iter()
        .map(|f| f.parse::<u32>().unwrap())
        .max()
        .unwrap();
    let mut bake = Bake::start(&solver, &out, &[BakeFormat::Pc2, BakeFormat::Glb]).unwrap();
    for frame in 1..=last {
        solver.step();
        bake.record(&solver).unwrap();
        if frames.contains(&frame.to_string().as_str()) {
            // sinew's own positions, in metres: muscles, then bone meshes posed.
            let unit = solver.settings.length_unit;
            let muscles = solver
                .muscles()
                .iter()
                .flat_map(|m| m.surface_positions().to_vec());
            let bones = solver
                .bones()
                .iter()
                .filter_map(|b| b.target.map(|t| (b, t)));
            let bones = bones.flat_map(|(b, t)| {
                let target = &solver.targets()[t];
                target
                    .positions()
                    .iter()
                    .map(|&p| b.transform.transform_point3(p))
                    .collect::<Vec<_>>()
            });
            let bytes: Vec<u8> = muscles
                .chain(bones)
                .flat_map(|p| (p / unit).to_array())
                .flat_map(f32::to_le_bytes)
                .collect();
            std::fs::write(expected.join(format!("{frame}.f32")), bytes).unwrap();
        }
    }
    bake.finish().unwrap();
    let Some((ok, text)) = blender_check("check_bake.py", &out, frames, Some(&expected)) else {
        eprintln!("skipped: `blender` is not on the PATH (apt-get install blender python3-numpy)");
        return;
    };
    for line in text.lines().filter(|l| l.starts_with("RESULT")) {
        eprintln!("{line}");
    }
    assert!(ok, "Blender disagrees with the bake:\n{text}");
    std::fs::remove_dir_all(dir).unwrap();
}
