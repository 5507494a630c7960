//! Bad input gives typed errors naming the file, element and reason; nothing panics.

use sinew_core::error::{BuildError, MeshError, SceneError};
use sinew_core::mesh::{LoadOptions, SurfaceMesh, load_mesh};
use sinew_core::muscle::{AttachmentDesc, MuscleDesc, MuscleParams, Roots, VertexMaps};
use sinew_core::scene::{Scene, builtin};
use sinew_core::{Solver, SolverSettings};
use std::path::{Path, PathBuf};

fn write(name: &str, text: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("sinew_bad_input_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

const CUBE: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";

fn oval_desc() -> MuscleDesc {
    let mesh = sinew_core::mesh::primitives::thesis_oval(Default::default())
        .build("oval")
        .unwrap();
    MuscleDesc {
        name: "oval".into(),
        mesh,
        roots: Roots::Vertices(vec![0]),
        attachments: Vec::new(),
        targets: Vec::new(),
        params: MuscleParams::default(),
        maps: VertexMaps::default(),
        binding: None,
    }
}

fn add(desc: MuscleDesc) -> Result<usize, BuildError> {
    Solver::new(SolverSettings::default())
        .unwrap()
        .add_muscle(desc)
}

#[test]
fn missing_file_names_the_file() {
    let err = load_mesh(
        Path::new("/nonexistent/muscle.obj"),
        &LoadOptions::default(),
    )
    .unwrap_err();
    assert!(matches!(err, MeshError::Io { .. }));
    assert!(err.to_string().contains("/nonexistent/muscle.obj"), "{err}");
}

#[test]
fn obj_without_faces() {
    let p = write("nofaces.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    let err = load_mesh(&p, &LoadOptions::default()).unwrap_err();
    assert!(matches!(err, MeshError::NoFaces { .. }), "{err}");
}

#[test]
fn obj_with_nan_or_inf_coordinates() {
    for (name, bad) in [("nan.obj", "nan"), ("inf.obj", "inf")] {
        let p = write(name, &format!("v 0 0 0\nv 1 0 {bad}\nv 0 1 0\nf 1 2 3\n"));
        match load_mesh(&p, &LoadOptions::default()) {
            Err(MeshError::NonFinite { vertex, .. }) => assert_eq!(vertex, 1),
            Err(MeshError::Parse { .. }) => {}
            other => panic!("{name}: expected a typed error, got {other:?}"),
        }
    }
}

#[test]
fn obj_face_past_the_vertex_list() {
    let p = write("past.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n");
    let err = load_mesh(&p, &LoadOptions::default()).unwrap_err();
    assert!(
        matches!(
            err,
            MeshError::IndexOutOfRange { .. } | MeshError::Parse { .. }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("past.obj"));
}

#[test]
fn open_mesh_with_volume_is_an_error_unless_allowed() {
    let open = CUBE
        .lines()
        .filter(|l| !l.starts_with("f 5 6 7 8"))
        .collect::<Vec<_>>()
        .join("\n");
    let p = write("open.obj", &open);
    let mesh = load_mesh(&p, &LoadOptions::default()).unwrap();
    let mut desc = oval_desc();
    desc.mesh = mesh;
    desc.roots = Roots::Vertices(vec![0]);
    let err = add(desc.clone()).unwrap_err();
    assert!(
        matches!(err, BuildError::Mesh(MeshError::Open { .. })),
        "{err}"
    );
    assert!(err.to_string().contains("open.obj"));
    desc.params.volume.allow_open_mesh = true;
    let mut solver = Solver::new(SolverSettings::default()).unwrap();
    let m = solver.add_muscle(desc).unwrap();
    assert!(
        solver.muscles()[m].constraints.volume.is_none(),
        "volume dropped for an open mesh"
    );
}

#[test]
fn degenerate_triangles() {
    let p = write("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n");
    let err = load_mesh(&p, &LoadOptions::default()).unwrap_err();
    assert!(
        matches!(err, MeshError::DegenerateFace { face: 0, .. }),
        "{err}"
    );
    // Repeated vertex in a face.
    let p = write("repeat.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 2\n");
    assert!(matches!(
        load_mesh(&p, &LoadOptions::default()),
        Err(MeshError::DegenerateFace { .. })
    ));
}

#[test]
fn non_manifold_edges() {
    // Three triangles on one edge.
    let p = write(
        "fin.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n",
    );
    let mesh = load_mesh(&p, &LoadOptions::default()).unwrap();
    let err = mesh.check_closed_manifold().unwrap_err();
    assert!(
        matches!(
            err,
            MeshError::NonManifoldEdge {
                a: 0,
                b: 1,
                faces: 3,
                ..
            }
        ),
        "{err}"
    );
    let mut desc = oval_desc();
    desc.mesh = mesh;
    assert!(matches!(
        add(desc),
        Err(BuildError::Mesh(MeshError::NonManifoldEdge { .. }))
    ));
}

#[test]
fn root_vertex_out_of_range() {
    let mut desc = oval_desc();
    desc.roots = Roots::Vertices(vec![92]);
    let err = add(desc).unwrap_err();
    assert!(
        matches!(
            err,
            BuildError::RootOutOfRange {
                vertex: 92,
                count: 92,
                ..
            }
        ),
        "{err}"
    );
}

#[test]
fn no_roots_and_no_way_to_infer_them() {
    let mut desc = oval_desc();
    desc.roots = Roots::Attachments;
    let err = add(desc).unwrap_err();
    assert!(matches!(err, BuildError::NoRoots { .. }), "{err}");
}

#[test]
fn negative_or_nan_stiffness() {
    for bad in [-1.0, f32::NAN] {
        let mut desc = oval_desc();
        desc.params.compliance.fiber = bad;
        let err = add(desc).unwrap_err();
        assert!(
            matches!(&err, BuildError::InvalidParameter { parameter, .. } if parameter.contains("Fiber")),
            "{err}"
        );
    }
}

#[test]
fn a_hold_release_out_of_range_is_refused_by_name() {
    for bad in [0.0, 1.5, f32::NAN] {
        let mut desc = oval_desc();
        desc.params.hold_shape = true;
        desc.params.hold_release = bad;
        let err = add(desc).unwrap_err();
        assert!(
            matches!(&err, BuildError::InvalidParameter { parameter, .. } if parameter == "hold_release"),
            "{err}"
        );
    }
}

#[test]
fn an_unknown_area_mode_in_a_scene_is_a_syntax_error_naming_it() {
    let mut scene = builtin("P1").unwrap();
    scene.muscles[0].params.area_mode = sinew_core::constraints::AreaMode::NoShrink;
    let text = ron::ser::to_string_pretty(&scene, Default::default()).unwrap();
    assert!(
        text.contains("area_mode: NoShrink"),
        "written when not the default"
    );
    let p = write("area_mode.ron", &text.replace("NoShrink", "Shrinkless"));
    match Scene::load(&p) {
        Err(e @ SceneError::Syntax { .. }) => assert!(e.to_string().contains("Shrinkless"), "{e}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn activation_outside_unit_range_is_clamped_and_reported_once() {
    let mut solver = builtin("T1").unwrap().instantiate(Path::new(".")).unwrap();
    solver.set_activation_curve(0, None);
    solver.set_activation(0, 1.7);
    solver.step();
    assert_eq!(solver.muscles()[0].params.activation, 1.0);
    solver.set_activation(0, -3.0);
    solver.step();
    assert_eq!(solver.muscles()[0].params.activation, 0.0);
    let warnings = solver.take_warnings();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("1.7"));
}

#[test]
fn attachment_to_a_missing_bone() {
    let mut scene = builtin("P1").unwrap();
    scene.muscles[0].attachments[0].bone = Some("humerus".into());
    let err = scene.instantiate(Path::new(".")).unwrap_err();
    assert!(
        matches!(&err, SceneError::UnknownReference { kind: "bone", name, .. } if name == "humerus"),
        "{err}"
    );
    let mut desc = oval_desc();
    desc.attachments = vec![AttachmentDesc {
        bone: Some(3),
        vertex: Some(0),
        ..Default::default()
    }];
    assert!(matches!(
        add(desc),
        Err(BuildError::InvalidParameter { .. })
    ));
}

#[test]
fn ron_syntax_error_has_line_and_column() {
    let p = write("broken.ron", "Scene(\n    name: \"x\",\n    frames: ,\n)\n");
    match Scene::load(&p) {
        Err(SceneError::Syntax {
            line, column, file, ..
        }) => {
            assert_eq!(line, 3);
            assert!(column > 1);
            assert!(file.ends_with("broken.ron"));
        }
        other => panic!("expected a syntax error, got {other:?}"),
    }
}

#[test]
fn closed_quad_cube_loads_welded_with_exact_volume() {
    // Duplicate every position (as exporters do at UV seams): welding restores the cube.
    let mut split = String::new();
    let mut faces = String::new();
    let verts: Vec<&str> = CUBE.lines().filter(|l| l.starts_with("v ")).collect();
    for (i, f) in CUBE.lines().filter(|l| l.starts_with("f ")).enumerate() {
        faces.push('f');
        for (k, idx) in f[2..].split_whitespace().enumerate() {
            let v: usize = idx.parse().unwrap();
            split.push_str(verts[v - 1]);
            split.push('\n');
            faces.push_str(&format!(" {}", i * 4 + k + 1));
        }
        faces.push('\n');
    }
    let p = write("split.obj", &(split + &faces));
    let mesh: SurfaceMesh = load_mesh(&p, &LoadOptions::default()).unwrap();
    assert_eq!(mesh.vertex_count(), 8);
    assert_eq!(mesh.polygon_count(), 6, "quads stay quads");
    assert_eq!(mesh.edges.len(), 12);
    assert!(mesh.check_closed_manifold().is_ok());
    assert!((mesh.volume() - 1.0).abs() < 1e-9);
    let tri = load_mesh(
        &p,
        &LoadOptions {
            triangulate: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(tri.edges.len(), 18, "triangulation adds the diagonals");
    // Without welding the same file is 24 separate vertices and open.
    let raw = load_mesh(
        &p,
        &LoadOptions {
            weld_tolerance: None,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(raw.vertex_count(), 24);
    assert!(raw.check_closed_manifold().is_err());
}

#[test]
fn stl_ascii_loads_and_welds() {
    let tri = |a: [f32; 3], b: [f32; 3], c: [f32; 3]| {
        format!(
            "facet normal 0 0 0\nouter loop\nvertex {} {} {}\nvertex {} {} {}\nvertex {} {} {}\nendloop\nendfacet\n",
            a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]
        )
    };
    let (o, x, y, z) = ([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
    let text = format!(
        "solid tet\n{}{}{}{}endsolid tet\n",
        tri(o, y, x),
        tri(o, x, z),
        tri(o, z, y),
        tri(x, y, z)
    );
    let p = write("tet.stl", &text);
    let mesh = load_mesh(&p, &LoadOptions::default()).unwrap();
    assert_eq!(mesh.vertex_count(), 4);
    assert!(mesh.check_closed_manifold().is_ok());
    assert!((mesh.volume() - 1.0 / 6.0).abs() < 1e-7);
    let p = write("garbage.stl", "solid x\nfacet oops\n");
    assert!(load_mesh(&p, &LoadOptions::default()).is_err());
}

#[test]
fn inconsistent_orientation_is_detected() {
    let flipped = CUBE.replace("f 5 6 7 8", "f 8 7 6 5");
    let p = write("flipped.obj", &flipped);
    let mesh = load_mesh(&p, &LoadOptions::default()).unwrap();
    assert!(matches!(
        mesh.check_closed_manifold(),
        Err(MeshError::InconsistentOrientation { .. })
    ));
}
