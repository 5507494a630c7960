//! The Bevy driver and the plain one run the same pipeline: on the arm (T5,
//! a skeleton and sensors), the full body (T7, 144 muscles) and a skin bound
//! to a moving bone they agree bit for bit with every method at 1, 2 and 8
//! threads, and the colour sweeps across muscles are taken by both.

use crate::common;

use bevy::prelude::*;
use sinew_bevy::prelude::*;
use sinew_core::scene::Scene;
use sinew_core::{Solver, SolverMethod, SweepSchedule};
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn asset(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets")
        .join(path)
}

/// What one configuration did: whether the bits agreed, and the iterations
/// each driver swept by colour.
struct Run {
    differs: Option<String>,
    plain_by_color: u32,
    bevy_by_color: u32,
}

/// Steps `base` (built once) and an app spawned from a clone of it with
/// `method`, `threads` and `schedule` for `frames` frames.
fn run(
    scene: &Scene,
    base: &Solver,
    method: SolverMethod,
    threads: u32,
    schedule: SweepSchedule,
    frames: usize,
) -> Run {
    let mut plain = base.clone();
    plain.settings.method = method;
    plain.settings.threads = threads;
    plain.settings.schedule = schedule;
    let mut parts = base.clone().into_parts();
    parts.settings = plain.settings.clone();
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        bevy::transform::TransformPlugin,
        SinewPlugin::default().every_update(),
    ));
    let root = app
        .world_mut()
        .spawn(SinewSceneRoot::Built(Arc::new(SinewScene {
            scene: scene.clone(),
            parts,
        })))
        .id();
    let (mut plain_by_color, mut bevy_by_color) = (0, 0);
    for _ in 0..frames {
        plain.step();
        app.update();
        plain_by_color += plain.timings().sweeps_by_color;
        bevy_by_color += app.world().resource::<SinewTimings>().step.sweeps_by_color;
    }
    let muscles = common::scene_muscles(&app, root);
    assert_eq!(muscles.len(), plain.muscles().len());
    let differs = plain.muscles().iter().zip(&muscles).find_map(|(m, &e)| {
        let ecs = &app.world().get::<MuscleState>(e).unwrap().muscle.x;
        let same = m.x.len() == ecs.len()
            && m.x
                .iter()
                .zip(ecs)
                .all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits));
        (!same).then(|| m.name.clone())
    });
    Run {
        differs,
        plain_by_color,
        bevy_by_color,
    }
}

/// Every method at 1, 2 and 8 threads (the scene's own schedule), then the
/// clustered methods swept by colour; returns the iterations swept by colour.
fn agree_on(scene_file: &str, frames: usize) {
    let path = asset(scene_file);
    let scene = Scene::load(&path).unwrap();
    let base = scene.instantiate(path.parent().unwrap()).unwrap();
    agree_on_scene(scene_file, &scene, &base, frames, true);
}

/// [`agree_on`] for a scene already built (`base`); `large`: big enough
/// that the colour sweeps must run by colour when asked to.
fn agree_on_scene(scene_file: &str, scene: &Scene, base: &Solver, frames: usize, large: bool) {
    let mut configs: Vec<_> = SolverMethod::EVERY
        .iter()
        .flat_map(|&m| [1, 2, 8].map(|t| (m, t, SweepSchedule::Auto)))
        .collect();
    for method in [SolverMethod::EVERY[2], SolverMethod::EVERY[4]] {
        configs.extend([2, 8].map(|t| (method, t, SweepSchedule::ByColor)));
    }
    let mut failures = Vec::new();
    for (method, threads, schedule) in configs {
        let r = run(scene, base, method, threads, schedule, frames);
        if let Some(muscle) = r.differs {
            failures.push(format!(
                "{method:?}, {threads} threads, {schedule:?}: '{muscle}' differs"
            ));
        }
        assert_eq!(
            r.plain_by_color, r.bevy_by_color,
            "{method:?}, {threads} threads, {schedule:?}: the drivers chose different schedules"
        );
        if large && schedule == SweepSchedule::ByColor {
            assert!(
                r.bevy_by_color > 0,
                "{method:?}, {threads} threads: no iteration was swept by colour"
            );
        }
    }
    assert!(failures.is_empty(), "{scene_file}: {failures:#?}");
}

#[test]
fn bevy_and_plain_agree_bit_for_bit_on_the_arm() {
    agree_on("scenes/t5.ron", 4);
}

#[test]
fn bevy_and_plain_agree_bit_for_bit_on_the_full_body() {
    agree_on("scenes/t7.ron", 2);
}

/// A skin bound to a moving bone over a muscle on it: the binding's bones
/// are the scene's, in the Bevy driver as in the plain one.
#[test]
fn bevy_and_plain_agree_bit_for_bit_on_a_bound_skin() {
    use sinew_core::animation::{TransformKey, TransformTrack};
    use sinew_core::glam::{Quat, Vec3};
    use sinew_core::mesh::primitives::MeshGenerator;
    use sinew_core::muscle::{MuscleParams, Roots};
    use sinew_core::scene::{AttachmentSpec, BoneSpec, MeshSource, MuscleSpec, SkinBindingSpec};
    let key = |time: f32, angle: f32| TransformKey {
        time,
        translation: Vec3::new(0.0, 0.2 * angle, 0.0),
        rotation: Quat::from_rotation_z(angle),
    };
    let ellipsoid = |radii: Vec3, n: u32| MeshGenerator::Ellipsoid {
        center: Vec3::ZERO,
        radii,
        segments: n,
        stacks: n,
    };
    let skin = ellipsoid(Vec3::new(0.08, 0.035, 0.035), 12);
    let skin_vertices = skin.build("skin").unwrap().vertex_count();
    let scene = Scene {
        name: "bound skin".into(),
        frames: 6,
        bones: vec![
            BoneSpec {
                name: "still".into(),
                ..Default::default()
            },
            BoneSpec {
                name: "arm".into(),
                track: TransformTrack {
                    keys: vec![key(0.0, 0.0), key(0.1, 0.5)],
                    ..Default::default()
                },
                ..Default::default()
            },
        ],
        muscles: vec![
            MuscleSpec {
                name: "belly".into(),
                mesh: MeshSource::Generator(ellipsoid(Vec3::new(0.06, 0.02, 0.02), 10)),
                roots: Roots::Attachments,
                attachments: [0, 91]
                    .map(|v| AttachmentSpec {
                        bone: Some("arm".into()),
                        vertex: Some(v),
                        ..Default::default()
                    })
                    .to_vec(),
                ..Default::default()
            },
            MuscleSpec {
                name: "skin".into(),
                mesh: MeshSource::Generator(skin),
                roots: Roots::Vertices(Vec::new()),
                targets: vec!["belly".into()],
                params: MuscleParams::surface_layer(1.1, 0.02),
                // Bone 1 of the scene (a binding names bones by scene index).
                binding: Some(SkinBindingSpec {
                    bones: vec!["arm".into()],
                    influences: vec![vec![(0, 1.0)]; skin_vertices],
                    strength: Vec::new(),
                }),
                ..Default::default()
            },
        ],
        ..Default::default()
    };
    let base = scene.instantiate(Path::new(".")).unwrap();
    assert_eq!(base.muscles()[1].binding.len(), skin_vertices);
    agree_on_scene("bound skin", &scene, &base, 6, false);
}
