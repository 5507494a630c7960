//! Fitting the anatomy (T7) to the MakeHuman character: per-segment
//! similarities put every limb joint of the anatomy on the character's, the
//! muscles follow the segments they lie along, and rig maps that name
//! what is not there are refused by name.

use sinew_core::Solver;
use sinew_core::character::fit::{AnatomyFit, RigMap, SkinVolume};
use sinew_core::character::{CharacterError, SkinnedCharacter, glb};
use sinew_core::glam::Affine3A;
use sinew_core::scene::Scene;
use std::path::{Path, PathBuf};

fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn makehuman_and_t7() -> (SkinnedCharacter, Solver, Vec<Affine3A>) {
    let character = glb::read(&repository().join("assets/characters/makehuman.glb"))
        .unwrap()
        .character;
    let path = repository().join("assets/scenes/t7.ron");
    let solver = Scene::load(&path)
        .unwrap()
        .instantiate(path.parent().unwrap())
        .unwrap();
    let rig = solver.skeleton().unwrap();
    let mut rest = Vec::new();
    rig.pose(&vec![0.0; rig.value_count()], &mut rest);
    (character, solver, rest)
}

#[test]
fn limb_joints_land_on_the_characters_and_the_muscles_follow() {
    let (character, solver, rest) = makehuman_and_t7();
    let rig = solver.skeleton().unwrap();
    let fit = AnatomyFit::new(&character, rig, &rest, &RigMap::game_engine()).unwrap();
    // Limbs: each segment's two ends on the character's joints.
    for (joint, body, child_joint, child_body) in [
        ("thigh_l", "femur_l", "calf_l", "tibia_l"),
        ("calf_r", "tibia_r", "foot_r", "talus_r"),
        ("upperarm_l", "humerus_l", "lowerarm_l", "ulna_l"),
        ("lowerarm_r", "ulna_r", "hand_r", "lunate_r"),
    ] {
        let b = rig.body_index(body).unwrap();
        let c = rig.body_index(child_body).unwrap();
        let j = character.joint(joint).unwrap();
        let k = character.joint(child_joint).unwrap();
        let at = |body: usize| fit.body(b).apply(rest[body].translation.into());
        let (start, end) = (at(b), at(c));
        assert!(
            start.distance(character.joints[j].origin) < 1e-5,
            "{body} start {start}"
        );
        assert!(
            end.distance(character.joints[k].origin) < 1e-5,
            "{body} end {end}"
        );
    }
    // The arms turn from hanging to the character's A-pose.
    let upperarm = fit.segments.iter().find(|s| s.body == "humerus_r").unwrap();
    let (_, turn) = upperarm.similarity.rotation.to_axis_angle();
    assert!(turn > 0.5, "the upper arm turned {turn} rad");
    // Muscles and bones inside the skin or not (#16 asks ≤ 1 % of muscle
    // vertices outside). This guards what the fit reaches today: 23.9 % of
    // muscle vertices and 4.3 % of bone vertices outside (muscles following
    // any nearby segment, e.g. the hanging hand's at the hip, gave 36 %;
    // without the fingers mapped and the trunk and head settled, bones 31 %).
    let mut fit = fit;
    let skin = SkinVolume::new(&character);
    let moved = fit.settle_in_skin(&solver, &skin, &RigMap::game_engine().free, 0.15);
    assert_eq!(moved.len(), 3, "{moved:?}");
    let geometry = fit.geometry(&solver);
    let share = |points: &mut dyn Iterator<Item = &sinew_core::glam::Vec3>| {
        let (outside, all) = points.fold((0, 0), |(o, a), &p| {
            (o + usize::from(skin.outside_by(p) > 0.0), a + 1)
        });
        outside as f32 / all as f32
    };
    let muscles = share(&mut geometry.muscles.iter().flatten());
    let bones = share(&mut geometry.bones.iter().flat_map(|(_, p)| p));
    eprintln!(
        "outside the skin: muscle vertices {:.1} %, bone vertices {:.1} %",
        100.0 * muscles,
        100.0 * bones
    );
    assert!(
        muscles < 0.26 && bones < 0.06,
        "muscles {muscles}, bones {bones}"
    );
}

#[test]
fn rig_maps_naming_what_is_not_there_are_refused() {
    let (character, solver, rest) = makehuman_and_t7();
    let rig = solver.skeleton().unwrap();
    let fit = |pairs: &[(&str, &str)]| {
        let map = RigMap {
            pairs: pairs.iter().map(|&(j, b)| (j.into(), b.into())).collect(),
            free: Vec::new(),
        };
        AnatomyFit::new(&character, rig, &rest, &map)
            .unwrap_err()
            .to_string()
    };
    let error = fit(&[("pelvis", "pelvis"), ("tail_01", "pelvis")]);
    assert!(
        error.contains("rig map pair 1") && error.contains("'tail_01'"),
        "{error}"
    );
    let error = fit(&[("thigh_l", "wing_l")]);
    assert!(
        error.contains("'wing_l'") && error.contains("no match"),
        "{error}"
    );
    // A RON map with an unknown field: the file and the line.
    let file = std::env::temp_dir().join(format!("sinew_rig_map_{}.ron", std::process::id()));
    std::fs::write(&file, "RigMap(\n  pairs: [],\n  bones: [],\n)").unwrap();
    match RigMap::load(&file) {
        Err(e @ CharacterError::Json { .. }) => {
            let text = e.to_string();
            assert!(
                text.contains(&file.display().to_string()) && text.contains("line 3"),
                "{text}"
            );
        }
        other => panic!("{other:?}"),
    }
    std::fs::remove_file(&file).unwrap();
}
