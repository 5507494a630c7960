//! The MJCF importer and the muscle-from-path builder on a small fixture
//! (`tests/data/mjcf/arm.xml`: two bones, an elbow, one muscle), and every
//! kind of bad input the importer must reject with a clear error.

use sinew_core::ImportError;
use sinew_core::glam::Vec3;
use sinew_core::import::builder::SweepOptions;
use sinew_core::import::mjcf::MjcfModel;
use sinew_core::import::{ImportOptions, UserMuscleMesh, import_model, z_up_to_y_up};
use sinew_core::skeleton::JointKind;
use std::path::{Path, PathBuf};

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mjcf/arm.xml")
}

/// A scratch directory for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("sinew_mjcf_{name}_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Writes `text` as an MJCF file next to the fixture's mesh directory.
fn model(dir: &Path, name: &str, text: &str) -> PathBuf {
    let meshes = dir.join("meshes");
    std::fs::create_dir_all(&meshes).unwrap();
    let bone = fixture().with_file_name("meshes/bone.obj");
    std::fs::copy(bone, meshes.join("bone.obj")).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn reads_includes_defaults_units_and_paths() {
    let m = MjcfModel::load(&fixture()).unwrap();
    assert_eq!(m.bodies.len(), 2);
    assert_eq!(m.bodies[1].parent, Some(0));
    // Joint axis and range come from the "limb" class via childclass; the
    // compiler in the included file says degrees.
    let elbow = &m.bodies[1].joints[0];
    assert_eq!(elbow.kind, JointKind::Hinge);
    assert_eq!(elbow.axis, Vec3::Y);
    let (lo, hi) = elbow.range.unwrap();
    assert!(lo.abs() < 1e-6 && (hi - 150f32.to_radians()).abs() < 1e-5);
    // euler="0 0 90" in degrees: a quarter turn about Z.
    let turned = m.bodies[1].quat * Vec3::X;
    assert!((turned - Vec3::Y).length() < 1e-5, "{turned}");
    assert_eq!(m.sites.len(), 4);
    assert_eq!(m.geoms.len(), 2);
    assert!(m.meshes[0].file.ends_with("meshes/bone.obj"));
    assert_eq!(m.tendons[0].sites.len(), 3);
    assert_eq!(m.actuators[0].force, Some(300.0));
    assert_eq!(m.couplings[0].joint, "elbow");
    assert_eq!(m.couplings[0].polynomial[0], 0.1);
}

#[test]
fn imports_a_scene_that_runs_in_y_up() {
    let dir = scratch("scene");
    let m = MjcfModel::load(&fixture()).unwrap();
    let imported = import_model(&m, &ImportOptions::default(), &dir, Path::new("meshes")).unwrap();
    let scene = imported.scene;
    assert_eq!(scene.muscles.len(), 1);
    assert_eq!(scene.bones.len(), 2);
    let flexor = &scene.muscles[0];
    // Held by the tip plus one ring at each end, on the bodies of the
    // first and last sites.
    let options = SweepOptions::default();
    assert_eq!(flexor.attachments.len(), 2 * (1 + options.around as usize));
    assert_eq!(flexor.attachments[0].bone.as_deref(), Some("upper"));
    assert_eq!(
        flexor.attachments.last().unwrap().bone.as_deref(),
        Some("fore")
    );
    assert!(flexor.targets.contains(&"upper".to_string()));
    let mut solver = scene.instantiate(&dir).unwrap();
    // Z-up → Y-up: the shoulder at MuJoCo (0, 0, 1) is at Bevy (0, 1, 0).
    let upper = &solver.bones()[solver.bone_index("upper").unwrap()];
    assert!((Vec3::from(upper.transform.translation) - Vec3::Y).length() < 1e-6);
    assert!((z_up_to_y_up() * Vec3::Z - Vec3::Y).length() < 1e-6);
    // The first vertex (a tip) sits on the origin site, in Y-up.
    let origin = upper
        .transform
        .transform_point3(Vec3::new(0.03, 0.0, -0.02));
    let tip = solver.muscles()[0].x[0];
    assert!(tip.distance(origin) < 2e-3, "{tip} vs {origin}");
    // No vertex starts inside a bone.
    let (inside, _) = (
        sinew_core::analysis::penetrating_vertices(&solver, 0.0)[0],
        0,
    );
    assert_eq!(inside, 0);
    for _ in 0..30 {
        solver.step();
    }
    assert!(solver.muscles()[0].x.iter().all(|p| p.is_finite()));
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn mirrored_attachment_reflects_and_renames() {
    let m = MjcfModel::load(&fixture()).unwrap();
    let mut host = MjcfModel::load(&fixture()).unwrap();
    host.attach(&m, "wrist", true).unwrap();
    let upper_l = host.body_index("upper_l").unwrap();
    assert_eq!(host.bodies[upper_l].parent, host.body_index("fore"));
    // Reflected through z = 0 of its frame: (0, 0, 1) → (0, 0, −1), then
    // placed at the wrist site.
    assert!((host.bodies[upper_l].pos - Vec3::new(0.0, 0.0, -0.25 - 1.0)).length() < 1e-6);
    assert!(host.actuators.iter().any(|a| a.name == "flexor_l"));
    assert!(host.tendon_sites(1).unwrap()[0].name == "origin_l");
    assert_eq!(host.couplings[1].joint, "elbow_l");
    // The left joint keeps its angle sense: its axis is −M·axis.
    let elbow_l = &host.bodies[host.body_index("fore_l").unwrap()].joints[0];
    assert_eq!(elbow_l.axis, Vec3::new(0.0, -1.0, 0.0));
    // Site names must exist.
    let err = host.attach(&m, "nowhere", false).unwrap_err();
    assert!(err.to_string().contains("nowhere"), "{err}");
}

#[test]
fn a_user_mesh_replaces_the_swept_one() {
    let dir = scratch("user");
    let m = MjcfModel::load(&fixture()).unwrap();
    // A spindle along the same path, made by the builder and saved as a file.
    let swept = sinew_core::import::builder::sweep_path(
        "mine",
        &[Vec3::new(0.03, 0.98, 0.0), Vec3::new(0.02, 0.64, 0.0)],
        Some(200.0),
        &SweepOptions::with_resolution(120),
    )
    .unwrap();
    let file = dir.join("mine.obj");
    sinew_core::import::write_obj(&file, &swept.mesh.positions, swept.mesh.polygons()).unwrap();
    let options = ImportOptions {
        user_meshes: vec![UserMuscleMesh {
            muscle: "flexor".into(),
            file: file.to_string_lossy().into_owned(),
        }],
        ..Default::default()
    };
    let imported = import_model(&m, &options, &dir, Path::new("meshes")).unwrap();
    let solver = imported.scene.instantiate(&dir).unwrap();
    assert_eq!(solver.muscles()[0].surface_count, swept.mesh.vertex_count());
    std::fs::remove_dir_all(dir).ok();
}

/// `held_rings` holds more rings at one end than `attach_rings` does: the
/// flexor's origin two rings of the swept mesh on the upper bone, its
/// insertion none (its tip alone) on the forearm; and on a user mesh the
/// rings round its tips by edge hops.
#[test]
fn held_rings_hold_more_or_fewer_rings_at_each_end() {
    let dir = scratch("held");
    let m = MjcfModel::load(&fixture()).unwrap();
    let around = SweepOptions::default().around as usize;
    // The flexor imported with `held_rings`, and how many of its
    // attachments are on the upper bone and on the forearm.
    let import_held = |held_rings, user_meshes| {
        let options = ImportOptions {
            held_rings: vec![held_rings],
            user_meshes,
            ..Default::default()
        };
        let scene = import_model(&m, &options, &dir, Path::new("meshes"))
            .unwrap()
            .scene;
        let flexor = &scene.muscles[0];
        let held = (on_bone(flexor, "upper"), on_bone(flexor, "fore"));
        (scene, held)
    };
    let (scene, held) = import_held(("flexor".into(), 2, 0), Vec::new());
    assert_eq!(held, (1 + 2 * around, 1));
    // The two rings are the two next to the origin's tip: vertices 1 to
    // 2 × around of the sweep, ring by ring.
    let mut upper: Vec<u32> = scene.muscles[0]
        .attachments
        .iter()
        .filter(|a| a.bone.as_deref() == Some("upper"))
        .filter_map(|a| a.vertex)
        .collect();
    upper.sort_unstable();
    assert_eq!(upper, (0..=2 * around as u32).collect::<Vec<_>>());
    let solver = scene.instantiate(&dir).unwrap();
    assert_eq!(solver.muscles()[0].attachments.len(), 2 + 2 * around);

    // A user mesh: the same sweep as a file, two rings at its insertion.
    let swept = sinew_core::import::builder::sweep_path(
        "mine",
        &[Vec3::new(0.03, 0.98, 0.0), Vec3::new(0.02, 0.64, 0.0)],
        Some(200.0),
        &SweepOptions::default(),
    )
    .unwrap();
    let file = dir.join("mine.obj");
    sinew_core::import::write_obj(&file, &swept.mesh.positions, swept.mesh.polygons()).unwrap();
    let user = vec![UserMuscleMesh {
        muscle: "flexor".into(),
        file: file.to_string_lossy().into_owned(),
    }];
    let (_, held) = import_held(("flexor".into(), 1, 2), user);
    assert_eq!(held, (1 + around, 1 + 2 * around));
    std::fs::remove_dir_all(dir).ok();
}

/// How many of `muscle`'s attachments are on `bone`.
fn on_bone(muscle: &sinew_core::scene::MuscleSpec, bone: &str) -> usize {
    let held = muscle.attachments.iter();
    held.filter(|a| a.bone.as_deref() == Some(bone)).count()
}

/// A per-muscle override naming a muscle that is not imported is an
/// error that names it and the option, not an override silently ignored.
#[test]
fn an_override_for_a_muscle_not_imported_is_an_error() {
    let dir = scratch("override");
    let m = MjcfModel::load(&fixture()).unwrap();
    let held = ImportOptions {
        held_rings: vec![("extensor".into(), 2, 2)],
        ..Default::default()
    };
    let result = import_model(&m, &held, &dir, Path::new("meshes")).map(|_| ());
    expect_err(result, &["held_rings", "extensor", "arm.xml"]);
    let radii = ImportOptions {
        radii: vec![("flexr".into(), 0.01)],
        ..Default::default()
    };
    let result = import_model(&m, &radii, &dir, Path::new("meshes")).map(|_| ());
    expect_err(result, &["radii", "flexr"]);
    std::fs::remove_dir_all(dir).ok();
}

fn expect_err(result: Result<impl std::fmt::Debug, ImportError>, needles: &[&str]) {
    let err = result.expect_err("bad input must fail");
    let text = err.to_string();
    for n in needles {
        assert!(text.contains(n), "'{text}' should mention '{n}'");
    }
}

const BODY: &str = r#"<worldbody><body name="a" pos="0 0 1">
    <geom type="mesh" mesh="bone"/><site name="s0" pos="0.03 0 0"/><site name="s1" pos="0.03 0 -0.2"/>
    </body></worldbody>"#;

fn with(body: &str, rest: &str) -> String {
    format!(
        r#"<mujoco><compiler angle="radian" meshdir="meshes"/><asset><mesh name="bone" file="bone.obj"/></asset>
{body}
{rest}
</mujoco>"#
    )
}

/// A spatial tendon "t" through `sites` and the muscle "m" pulling on it.
fn muscle_through(sites: &[&str]) -> String {
    let path: String = sites
        .iter()
        .map(|s| format!("<site site=\"{s}\"/>\n"))
        .collect();
    format!(
        "<tendon><spatial name=\"t\">{path}</spatial></tendon>\n\
         <actuator><muscle name=\"m\" tendon=\"t\" force=\"100\"/></actuator>"
    )
}

fn import(path: &Path) -> Result<(), ImportError> {
    let m = MjcfModel::load(path)?;
    let dir = path.parent().unwrap();
    import_model(&m, &ImportOptions::default(), dir, Path::new("out")).map(|_| ())
}

#[test]
fn malformed_xml_names_file_and_line() {
    let dir = scratch("xml");
    let p = model(
        &dir,
        "broken.xml",
        "<mujoco>\n<worldbody>\n<body name=\"a\">\n</worldbody>\n</mujoco>\n",
    );
    expect_err(MjcfModel::load(&p), &["broken.xml:4", "malformed XML"]);
    let p = model(&dir, "root.xml", "<robot/>");
    expect_err(MjcfModel::load(&p), &["root.xml", "<mujoco>"]);
}

#[test]
fn missing_include_is_an_error() {
    let dir = scratch("include");
    let p = model(
        &dir,
        "inc.xml",
        "<mujoco>\n  <include file=\"nope.xml\"/>\n</mujoco>",
    );
    expect_err(
        MjcfModel::load(&p),
        &["inc.xml:2", "nope.xml", "does not exist"],
    );
}

#[test]
fn unknown_mesh_file_is_an_error() {
    let dir = scratch("mesh");
    let text = with(BODY, "").replace("bone.obj", "femur.stl");
    let p = model(&dir, "mesh.xml", &text);
    expect_err(import(&p), &["femur.stl"]);
    let text = with(BODY, "").replace("mesh=\"bone\"", "mesh=\"tibia\"");
    let p = model(&dir, "asset.xml", &text);
    expect_err(import(&p), &["tibia", "mesh asset"]);
}

#[test]
fn tendon_naming_a_missing_site_is_an_error() {
    let dir = scratch("site");
    let text = with(BODY, &muscle_through(&["s0", "ghost"]));
    let p = model(&dir, "site.xml", &text);
    expect_err(import(&p), &["site.xml:", "'ghost'", "tendon 't'"]);
}

#[test]
fn unsupported_joint_types_are_named() {
    let dir = scratch("joint");
    let body = BODY.replace("<geom", "<joint name=\"root\" type=\"free\"/><geom");
    let p = model(&dir, "free.xml", &with(&body, ""));
    expect_err(MjcfModel::load(&p), &["free.xml:", "root", "'free'"]);
    let body = BODY.replace("<geom", "<freejoint/><geom");
    let p = model(&dir, "freejoint.xml", &with(&body, ""));
    expect_err(MjcfModel::load(&p), &["freejoint", "not supported"]);
}

#[test]
fn short_and_degenerate_paths_are_errors() {
    let dir = scratch("path");
    let one = with(BODY, &muscle_through(&["s0"]));
    let p = model(&dir, "one.xml", &one);
    expect_err(import(&p), &["muscle 'm'", "1 point"]);
    let zero = with(BODY, &muscle_through(&["s0", "s0", "s1"]));
    let p = model(&dir, "zero.xml", &zero);
    expect_err(import(&p), &["muscle 'm'", "segment 0", "zero length"]);
}

#[test]
fn non_positive_radius_is_an_error() {
    let dir = scratch("radius");
    let m = MjcfModel::load(&fixture()).unwrap();
    for radius in [0.0, -0.01, f32::NAN] {
        let mut options = ImportOptions::default();
        options.sweep.radius = Some(radius);
        expect_err(
            import_model(&m, &options, &dir, Path::new("out")),
            &["muscle 'flexor'", "radius"],
        );
    }
    let options = ImportOptions {
        muscles: vec!["biceps".into()],
        ..Default::default()
    };
    expect_err(
        import_model(&m, &options, &dir, Path::new("out")),
        &["unknown muscle", "biceps"],
    );
}

#[test]
fn bone_slivers_are_dropped_not_fatal() {
    let dir = scratch("sliver");
    let path = model(&dir, "sliver.xml", &with(BODY, ""));
    // The box plus a zero-area sliver: fatal for a muscle, harmless for a bone.
    let bone = dir.join("meshes/bone.obj");
    let mut text = std::fs::read_to_string(&bone).unwrap();
    text.push_str("v 0 0 0.15\nf 8 9 2\n");
    std::fs::write(&bone, text).unwrap();
    let m = MjcfModel::load(&path).unwrap();
    let options = ImportOptions {
        bone_meshes: sinew_core::import::BoneMeshes::All,
        ..Default::default()
    };
    let imported = import_model(&m, &options, &dir, Path::new("out")).unwrap();
    assert!(imported.scene.bones[0].shape.is_some());
    imported.scene.instantiate(&dir).unwrap();
    std::fs::remove_dir_all(dir).ok();
}

/// A muscle from `s0` to `s1` whose tendon wraps a 20 mm sphere half-way,
/// on the side of a side site at +X (the straight path runs through the
/// sphere's centre).
fn wrapped(geom: &str, wrap: &str) -> String {
    let body = BODY.replace(
        "<site name=\"s1\"",
        &format!("{geom}<site name=\"side\" pos=\"0.08 0 -0.1\"/><site name=\"s1\""),
    );
    let tendon = format!(
        "<tendon><spatial name=\"t\"><site site=\"s0\"/>{wrap}<site site=\"s1\"/></spatial></tendon>\n\
         <actuator><muscle name=\"m\" tendon=\"t\" force=\"100\"/></actuator>"
    );
    with(&body, &tendon)
}

const BALL: &str = r#"<geom name="ball" size="0.02" pos="0.03 0 -0.1"/>"#;

#[test]
fn a_tendon_wraps_around_its_geom_on_the_side_of_its_side_site() {
    let dir = scratch("wrap");
    let path = model(
        &dir,
        "wrap.xml",
        &wrapped(BALL, r#"<geom geom="ball" sidesite="side"/>"#),
    );
    let m = MjcfModel::load(&path).unwrap();
    assert_eq!(m.wrap_geoms.len(), 1);
    assert_eq!(m.tendons[0].wraps.len(), 1);
    assert_eq!(m.tendons[0].wraps[0].after, 1);
    // The ball's centre in the scene (Y-up); the muscle's centre line is
    // its internal points (one per ring).
    let ball = z_up_to_y_up() * Vec3::new(0.03, 0.0, 0.9);
    let side = z_up_to_y_up() * Vec3::X;
    let centre_line = |wrap_paths: bool| {
        let options = ImportOptions {
            wrap_paths,
            ..Default::default()
        };
        let imported = import_model(&m, &options, &dir, Path::new("out")).unwrap();
        let solver = imported.scene.instantiate(&dir).unwrap();
        let muscle = &solver.muscles()[0];
        (muscle.internal_positions().to_vec(), imported.notes)
    };
    let (wrapped, notes) = centre_line(true);
    let nearest = wrapped
        .iter()
        .map(|p| p.distance(ball))
        .fold(f32::INFINITY, f32::min);
    assert!(
        nearest > 0.019,
        "the centre line comes {nearest} m from the ball's centre"
    );
    assert!(wrapped.iter().all(|p| (*p - ball).dot(side) > -1e-3));
    assert!(!notes.iter().any(|n| n.contains("ignored")), "{notes:?}");
    let (straight, notes) = centre_line(false);
    let nearest = straight
        .iter()
        .map(|p| p.distance(ball))
        .fold(f32::INFINITY, f32::min);
    assert!(
        nearest < 0.01,
        "the straight path passes {nearest} m from the centre"
    );
    assert!(
        notes
            .iter()
            .any(|n| n.contains("1 wrapping geom(s) ignored")),
        "{notes:?}"
    );
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn a_wrap_around_a_missing_or_sizeless_geom_is_an_error() {
    let dir = scratch("wrap_bad");
    let options = ImportOptions {
        wrap_paths: true,
        ..Default::default()
    };
    let wrap = r#"<geom geom="ball" sidesite="side"/>"#;
    for (name, geom, needles) in [
        (
            "missing.xml",
            "",
            &["tendon 't'", "geom 'ball'", "does not exist"][..],
        ),
        (
            "sizeless.xml",
            r#"<geom name="ball" pos="0.03 0 -0.1"/>"#,
            &["tendon 't'", "geom 'ball'", "positive"][..],
        ),
    ] {
        let path = model(&dir, name, &wrapped(geom, wrap));
        let m = MjcfModel::load(&path).unwrap();
        expect_err(import_model(&m, &options, &dir, Path::new("out")), needles);
    }
    // A wrap must lie between two sites (MuJoCo's rule): first or last is
    // an error when the model is read.
    let first = wrapped(BALL, "").replace(
        "<spatial name=\"t\"><site site=\"s0\"/>",
        "<spatial name=\"t\"><geom geom=\"ball\"/><site site=\"s0\"/>",
    );
    assert!(first.contains("<geom geom=\"ball\"/><site site=\"s0\"/>"));
    let path = model(&dir, "first.xml", &first);
    expect_err(
        MjcfModel::load(&path),
        &["first.xml:", "tendon 't'", "between two sites"],
    );
    let path = model(
        &dir,
        "noside.xml",
        &wrapped(BALL, r#"<geom geom="ball" sidesite="nowhere"/>"#),
    );
    let m = MjcfModel::load(&path).unwrap();
    expect_err(
        import_model(&m, &options, &dir, Path::new("out")),
        &["tendon 't'", "site 'nowhere'"],
    );
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn a_mirrored_tendon_wraps_a_geom_both_sides_share() {
    use sinew_core::import::mjcf::{MjWrapGeom, WrapShape};
    let thorax = MjWrapGeom {
        name: "thorax".into(),
        body: None,
        shape: WrapShape::Sphere { radius: 0.08 },
        pos: Vec3::ZERO,
        quat: sinew_core::glam::Quat::IDENTITY,
    };
    let right = MjWrapGeom {
        name: "ball_r".into(),
        ..thorax.clone()
    };
    let m = MjcfModel {
        wrap_geoms: vec![thorax, right],
        ..Default::default()
    };
    // The left arm's copy of a tendon names `thorax_l`: the host has one
    // thorax for both sides.
    assert_eq!(m.wrap_geom("thorax_l").unwrap().name, "thorax");
    assert_eq!(m.wrap_geom("thorax").unwrap().name, "thorax");
    // A right-side geom is never taken for a missing left one.
    assert!(m.wrap_geom("ball_l").is_none());
}
