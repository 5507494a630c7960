//! One length unit: a scene authored in centimetres (`length_unit: 100`,
//! geometry ×100, every physical parameter still SI) moves as the same
//! scene in metres, ×100 — gravity, masses from density, Volume's
//! compliance and the contact reach all converted by the unit; and
//! `sinew check`'s figures are SI in both.

use sinew_core::glam::Vec3;
use sinew_core::mesh::{LoadOptions, SurfaceMesh};
use sinew_core::muscle::MuscleParams;
use sinew_core::scene::{AttachmentSpec, BoneShape, BoneSpec, MeshSource, MuscleSpec, Scene};
use sinew_core::{Solver, SolverMethod, SolverSettings, analysis};
use std::path::{Path, PathBuf};

const MESH: &str = "../meshes/myoarm/BRD.obj";

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenes")
}

/// The brachioradialis (from myo-sim) held at its two tips, contracting at
/// `activation`, sagging under gravity onto a ground plane 1.5 mm below its
/// lowest vertex (within the contact reach), with a compliant volume —
/// authored in scene units of `1/unit` m. (Not the brachialis, which this
/// test used until T3–T6's paths wrapped their geoms: swept round its
/// cylinder, under Jacobi one of its vertices lies on the edge of a
/// decision that the two scenes' rounding takes apart between frames 5
/// and 10 — a 42 µm step, constant after — where the brachioradialis,
/// the pronator and the flexor carpi radialis stay within 2e-6 of their
/// length.)
fn brachioradialis_over_ground(unit: f32, method: SolverMethod, activation: f32) -> Solver {
    let mesh = SurfaceMesh::load(&scenes_dir().join(MESH), &LoadOptions::default()).unwrap();
    let axis = sinew_core::muscle::longest_axis(&mesh.positions);
    let key = |i: &usize| mesh.positions[*i].dot(axis);
    let n = mesh.positions.len();
    let tips = [
        (0..n).min_by(|a, b| key(a).total_cmp(&key(b))).unwrap(),
        (0..n).max_by(|a, b| key(a).total_cmp(&key(b))).unwrap(),
    ];
    let low = mesh.positions.iter().map(|p| p.y).fold(f32::MAX, f32::min);
    let centre = mesh.positions.iter().sum::<Vec3>() / n as f32;
    let mut params = MuscleParams {
        activation,
        ..Default::default()
    };
    params.compliance.volume = 1e-6;
    Scene {
        name: format!("brachioradialis in units of 1/{unit} m"),
        settings: SolverSettings {
            gravity: Vec3::new(0.0, -9.81, 0.0),
            length_unit: unit,
            method,
            threads: 1,
            ..Default::default()
        },
        bones: vec![BoneSpec {
            name: "ground".into(),
            shape: Some(BoneShape::Plane {
                center: Vec3::new(centre.x, low - 0.0015, centre.z) * unit,
                normal: Vec3::Y,
                size: 0.4 * unit,
            }),
            ..Default::default()
        }],
        muscles: vec![MuscleSpec {
            name: "BRA".into(),
            mesh: MeshSource::File {
                path: MESH.into(),
                triangulate: false,
                scale: unit,
                orient_outward: false,
                translation: sinew_core::glam::Vec3::ZERO,
            },
            attachments: tips
                .iter()
                .map(|&v| AttachmentSpec {
                    vertex: Some(v as u32),
                    ..Default::default()
                })
                .collect(),
            targets: vec!["ground".into()],
            params,
            ..Default::default()
        }],
        ..Default::default()
    }
    .instantiate(&scenes_dir())
    .unwrap()
}

#[test]
fn a_scene_in_centimetres_moves_as_the_scene_in_metres() {
    let methods = [
        SolverMethod::Sequential,
        SolverMethod::Jacobi { omega: 1.5 },
    ];
    for (method, activation) in methods.into_iter().flat_map(|m| [(m, 0.0), (m, 0.3)]) {
        let mut metres = brachioradialis_over_ground(1.0, method, activation);
        let mut centimetres = brachioradialis_over_ground(100.0, method, activation);
        let start = metres.muscles()[0].x.clone();
        for _ in 0..60 {
            metres.step();
            centimetres.step();
        }
        let (m, cm) = (&metres.muscles()[0], &centimetres.muscles()[0]);
        let moved =
            m.x.iter()
                .zip(&start)
                .map(|(a, b)| a.distance(*b))
                .fold(0.0, f32::max);
        let worst =
            m.x.iter()
                .zip(&cm.x)
                .map(|(a, b)| a.distance(*b / 100.0))
                .fold(0.0, f32::max);
        // Relative to the muscle's length (f32 rounds positions to 1e-7 of
        // their size; 60 frames of iterations accumulate it).
        let axis = sinew_core::muscle::longest_axis(&start);
        let (lo, hi) = start.iter().fold((f32::MAX, f32::MIN), |(lo, hi), p| {
            (lo.min(p.dot(axis)), hi.max(p.dot(axis)))
        });
        let relative = worst / (hi - lo);
        println!(
            "{method:?}, activation {activation}: moved up to {:.2} mm; the cm scene ÷ 100 is {:.1e} m from the m scene ({relative:.1e} of the muscle's {:.0} mm)",
            moved * 1e3,
            worst,
            (hi - lo) * 1e3
        );
        assert!(moved > 5e-4, "the muscle must move ({moved} m)");
        // `sinew check`'s figures are SI in both.
        let errors = |s: &Solver| analysis::attachment_errors(s).fold(0.0, f32::max);
        let (e_m, e_cm) = (errors(&metres), errors(&centimetres));
        assert!(
            (e_m - e_cm).abs() <= 1e-6,
            "attachment error {e_m} m vs {e_cm} m"
        );
        let deep = |s: &Solver| analysis::penetrating_vertices(s, 1e-4);
        assert_eq!(deep(&metres), deep(&centimetres));
        assert!(
            relative < 1e-5,
            "{method:?}, activation {activation}: {worst} m apart"
        );
    }
}
