//! The thesis' reference scenes, rebuilt from generators (SPEC §10.1).
//!
//! | Scene | Content | Thesis constraints |
//! |---|---|---|
//! | P1 | 10×10 oval held at both ends, a plane | 571 |
//! | P2 | oval + box, each held by one end vertex, connected, a plane | 1040 |
//! | T1 | the oval activating 0 → 1 → 0 over 120 frames, no targets | — |
//! | P3 | two-headed "biceps" (496 vertices) + "brachialis" (170), a plane | 4035 |

use super::{AttachmentSpec, BoneShape, BoneSpec, MeshSource, MuscleSpec, Scene};
use crate::animation::{Curve, Interpolation};
use crate::mesh::primitives::{MeshGenerator, thesis_oval};
use crate::muscle::{MuscleParams, Roots, nearest_vertex};
use crate::solver::SolverSettings;
use glam::Vec3;

/// Names accepted by [`builtin`].
pub const BUILTIN_SCENES: [&str; 4] = ["P1", "P2", "T1", "P3"];

/// A reference scene by name (case-insensitive), or `None`.
pub fn builtin(name: &str) -> Option<Scene> {
    match name.to_ascii_uppercase().as_str() {
        "P1" => Some(p1()),
        "P2" => Some(p2()),
        "T1" => Some(t1()),
        "P3" => Some(p3()),
        _ => None,
    }
}

fn profiling_settings() -> SolverSettings {
    SolverSettings {
        iterations: 5,
        gravity: Vec3::new(0.0, -9.81, 0.0),
        ..Default::default()
    }
}

fn ground(y: f32, size: f32) -> BoneSpec {
    BoneSpec {
        name: "ground".into(),
        shape: Some(BoneShape::Plane {
            center: Vec3::new(0.0, y, 0.0),
            normal: Vec3::Y,
            size,
        }),
        ..Default::default()
    }
}

fn pin(vertex: u32) -> AttachmentSpec {
    AttachmentSpec {
        vertex: Some(vertex),
        ..Default::default()
    }
}

fn oval(name: &str, center: Vec3) -> MuscleSpec {
    MuscleSpec {
        name: name.into(),
        mesh: MeshSource::Generator(thesis_oval(center)),
        roots: Roots::Vertices(vec![0]),
        ..Default::default()
    }
}

fn p1() -> Scene {
    let mut m = oval("oval", Vec3::ZERO);
    m.attachments = vec![pin(0), pin(91)];
    m.targets = vec!["ground".into()];
    Scene {
        name: "P1".into(),
        description: "Oval muscle held by two points at its ends; one static target (a plane)."
            .into(),
        frames: 120,
        settings: profiling_settings(),
        bones: vec![ground(-0.04, 0.4)],
        muscles: vec![m],
        ..Default::default()
    }
}

fn p2() -> Scene {
    let mut a = oval("oval", Vec3::new(-0.07, 0.0, 0.0));
    a.attachments = vec![pin(0)];
    a.targets = vec!["box".into(), "ground".into()];
    let box_gen = MeshGenerator::Box {
        center: Vec3::new(0.065, 0.0, 0.0),
        size: Vec3::new(0.1, 0.05, 0.05),
        divisions: [5, 3, 3],
    };
    // Roots: the whole end face at −X; held by one of its inner vertices.
    let mesh = box_gen.build("box").expect("valid generator");
    let min_x = mesh.bounds().0.x;
    let end_face: Vec<u32> = (0..mesh.vertex_count() as u32)
        .filter(|&i| (mesh.positions[i as usize].x - min_x).abs() < 1e-6)
        .collect();
    let held = end_face
        .iter()
        .copied()
        .min_by(|&i, &j| {
            let d = |k: u32| {
                let q = mesh.positions[k as usize];
                q.y * q.y + q.z * q.z
            };
            d(i).total_cmp(&d(j))
        })
        .expect("end face");
    let b = MuscleSpec {
        name: "box".into(),
        mesh: MeshSource::Generator(box_gen),
        roots: Roots::Vertices(end_face),
        attachments: vec![pin(held)],
        targets: vec!["oval".into(), "ground".into()],
        ..Default::default()
    };
    Scene {
        name: "P2".into(),
        description: "An oval and a box, each held by one end vertex; connected to each other and to a plane.".into(),
        frames: 120,
        settings: profiling_settings(),
        bones: vec![ground(-0.04, 0.5)],
        muscles: vec![a, b],
        ..Default::default()
    }
}

fn t1() -> Scene {
    let mut m = oval("oval", Vec3::ZERO);
    // Defaults: rotation-invariant fibres, +20 % volume at full activation.
    m.params = MuscleParams::default();
    m.activation = Some(Curve {
        keys: vec![
            (0.0, 0.0),
            (40.0 / 60.0, 1.0),
            (1.0, 1.0),
            (100.0 / 60.0, 0.0),
            (120.0 / 60.0, 0.0),
        ],
        interpolation: Interpolation::Smooth,
    });
    Scene {
        name: "T1".into(),
        description: "One oval muscle, no targets, activating 0 → 1 → 0 over 120 frames.".into(),
        frames: 120,
        settings: SolverSettings {
            iterations: 10,
            ..Default::default()
        },
        bones: Vec::new(),
        muscles: vec![m],
        ..Default::default()
    }
}

fn p3() -> Scene {
    let biceps_gen = MeshGenerator::Bifurcated {
        end: Vec3::new(0.16, 0.0, 0.0),
        junction: Vec3::new(-0.04, 0.0, 0.0),
        head_a: Vec3::new(-0.16, 0.01, 0.025),
        head_b: Vec3::new(-0.16, 0.01, -0.025),
        belly_radius: 0.022,
        head_radius: 0.012,
        half_around: 8,
        belly_rings: 17,
        head_rings: 11,
    };
    let biceps_mesh = biceps_gen.build("biceps").expect("valid generator");
    let n = biceps_mesh.vertex_count() as u32;
    // Tips: distal pole (0), the two head poles (last vertex of each head), and a
    // second distal vertex (first ring) — four attachment points as in P3.
    let head_b_tip = n - 1;
    let head_a_tip = nearest_vertex(&biceps_mesh.positions, Vec3::new(-0.16, 0.01, 0.025));
    let biceps = MuscleSpec {
        name: "biceps".into(),
        mesh: MeshSource::Generator(biceps_gen),
        roots: Roots::Attachments,
        attachments: vec![pin(0), pin(1), pin(head_a_tip), pin(head_b_tip)],
        targets: vec!["brachialis".into(), "ground".into()],
        ..Default::default()
    };
    let brachialis = MuscleSpec {
        name: "brachialis".into(),
        mesh: MeshSource::Generator(MeshGenerator::Fusiform {
            start: Vec3::new(-0.09, -0.04, 0.0),
            end: Vec3::new(0.13, -0.035, 0.0),
            belly_radius: 0.016,
            tendon_radius: 0.004,
            around: 12,
            rings: 14,
        }),
        roots: Roots::Attachments,
        attachments: vec![pin(0), pin(169)],
        targets: vec!["biceps".into(), "ground".into()],
        ..Default::default()
    };
    Scene {
        name: "P3".into(),
        description: "Two-headed biceps stand-in (496 vertices) and brachialis (170), connected to each other and a plane.".into(),
        frames: 120,
        settings: profiling_settings(),
        bones: vec![ground(-0.075, 0.6)],
        muscles: vec![biceps, brachialis],
        ..Default::default()
    }
}
