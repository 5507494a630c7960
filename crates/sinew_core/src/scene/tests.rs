use super::*;

#[test]
fn every_builtin_round_trips_through_ron() {
    for name in BUILTIN_SCENES {
        let scene = builtin(name).unwrap();
        let text = scene.to_ron().unwrap();
        let back = Scene::from_ron(&text, Path::new("mem.ron")).unwrap();
        assert_eq!(back, scene, "{name}");
    }
}

#[test]
fn plane_bone_faces_its_normal() {
    let mesh = bone_mesh(
        "ground",
        &BoneShape::Plane {
            center: Vec3::ZERO,
            normal: Vec3::Y,
            size: 1.0,
        },
        Path::new("."),
    )
    .unwrap();
    let mut normals = Vec::new();
    mesh.vertex_normals(&mesh.positions, &mut normals);
    assert!(normals.iter().all(|n| n.dot(Vec3::Y) > 0.999));
}

#[test]
fn duplicate_names_are_rejected() {
    let mut scene = builtin("P2").unwrap();
    scene.muscles[1].name = "oval".into();
    assert!(matches!(
        scene.instantiate(Path::new(".")),
        Err(SceneError::DuplicateName(_))
    ));
}

#[test]
fn holding_the_first_pose_removes_the_motion_and_keeps_the_start() {
    let mut scene = builtin("T1").unwrap();
    assert!(scene.motion_end() > 1.0, "T1 activates over time");
    let start = scene.muscles[0].activation.as_ref().unwrap().sample(0.0);
    scene.hold_first_pose();
    assert_eq!(scene.motion_end(), 0.0);
    let curve = scene.muscles[0].activation.as_ref().unwrap();
    assert_eq!(curve.sample(0.0), start);
    assert_eq!(curve.sample(1.0), start);
}

#[test]
fn relaxing_the_muscles_leaves_nothing_to_activate_them() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes/t5.ron");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut scene = Scene::from_ron(&text, &path).unwrap();
    assert!(
        scene.muscles.iter().any(|m| !m.drive.is_empty()),
        "T5's sensors drive its muscles"
    );
    scene.relax_muscles();
    for m in &scene.muscles {
        assert!(m.drive.is_empty() && m.activation.is_none(), "{}", m.name);
        assert_eq!(m.params.activation, 0.0, "{}", m.name);
    }
}
