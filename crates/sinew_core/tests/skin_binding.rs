//! A skin layer bound to a skeleton: the two-bone arm character's skin
//! (a capped tube, linear-blend skinned to the upper arm and the forearm)
//! over a biceps-like muscle from the upper arm to the forearm. Each skin
//! vertex is held softly to its skinned position (Bind) and slides on the
//! muscle at its rest gap (Sliding): at rest the skin is where skinning puts
//! it; when the elbow flexes with the biceps contracted, the biceps shortens
//! and bulges and the skin over it is pushed out beyond plain skinning while
//! the rest of the skin follows its bones — every method, same bits for any
//! thread count.

use sinew_core::analysis::{RunMetrics, Thresholds, skin_bind_distances, skin_bulges};
use sinew_core::animation::{TransformKey, TransformTrack};
use sinew_core::character::primitives::two_bone_arm;
use sinew_core::glam::{Quat, Vec3};
use sinew_core::mesh::SurfaceMesh;
use sinew_core::mesh::primitives::MeshGenerator;
use sinew_core::muscle::{
    AttachmentDesc, ConnectionWeights, MuscleDesc, MuscleParams, Roots, SkinBindingDesc, TargetRef,
    VertexMaps,
};
use sinew_core::{Solver, SolverMethod, SolverSettings};

const SEGMENT: f32 = 0.3;
const SKIN_RADIUS: f32 = 0.045;
/// The biceps: an ellipsoid in front of the humerus from 5 cm below the
/// shoulder to 5 cm below the elbow, its front 5 mm under the skin.
const BELLY_CENTER: Vec3 = Vec3::new(0.0, -0.2, 0.016);
const BELLY_RADII: Vec3 = Vec3::new(0.022, 0.15, 0.024);

fn track(keys: &[(f32, Vec3, Quat)]) -> TransformTrack {
    TransformTrack {
        keys: keys
            .iter()
            .map(|&(time, translation, rotation)| TransformKey {
                time,
                translation,
                rotation,
            })
            .collect(),
        ..Default::default()
    }
}

/// Upper arm still; the elbow flexes 90° forward between 1.5 and 2.5 s.
fn arm(method: SolverMethod, threads: u32) -> Solver {
    let settings = SolverSettings {
        method,
        threads,
        substeps: 2,
        iterations: 10,
        gravity: Vec3::new(0.0, -9.81, 0.0),
        ..Default::default()
    };
    let mut solver = Solver::new(settings).unwrap();
    let elbow = Vec3::new(0.0, -SEGMENT, 0.0);
    let flexed = Quat::from_rotation_x(-90f32.to_radians());
    // The humerus: a bar behind the biceps, 2 mm from it.
    let humerus = MeshGenerator::Box {
        center: Vec3::new(0.0, -0.15, -0.018),
        size: Vec3::new(0.016, 0.28, 0.016),
        divisions: [2, 14, 2],
    }
    .build("humerus")
    .unwrap();
    let upper = solver.add_bone(
        "upper_arm",
        track(&[(0.0, Vec3::ZERO, Quat::IDENTITY)]),
        Some(&humerus),
    );
    let forearm = solver.add_bone(
        "forearm",
        track(&[
            (0.0, elbow, Quat::IDENTITY),
            (1.5, elbow, Quat::IDENTITY),
            (2.5, elbow, flexed),
        ]),
        None,
    );
    let belly = MeshGenerator::Ellipsoid {
        center: BELLY_CENTER,
        radii: BELLY_RADII,
        segments: 16,
        stacks: 14,
    }
    .build("biceps")
    .unwrap();
    let tip = |bone: usize, y: f32| AttachmentDesc {
        bone: Some(bone),
        point: Some(BELLY_CENTER + Vec3::new(0.0, y, 0.0)),
        radius: 0.012,
        ..Default::default()
    };
    let biceps = solver
        .add_muscle(MuscleDesc {
            name: "biceps".into(),
            mesh: belly,
            roots: Roots::Attachments,
            attachments: vec![tip(upper, BELLY_RADII.y), tip(forearm, -BELLY_RADII.y)],
            targets: vec![TargetRef::Bone(upper)],
            // It slides on its bone and weak Hard ties (weight 0.05) keep
            // its shape at rest; it is free to bulge.
            params: MuscleParams {
                weights: ConnectionWeights {
                    sliding: 1.0,
                    soft: 0.0,
                    hard: 0.05,
                    normalize: false,
                },
                ..Default::default()
            },
            maps: VertexMaps::default(),
            binding: None,
        })
        .unwrap();
    let character = two_bone_arm(SEGMENT, SKIN_RADIUS, 1.5);
    let skin_mesh = SurfaceMesh::new(
        "arm skin",
        character.positions.clone(),
        &character
            .triangles
            .iter()
            .map(|t| t.to_vec())
            .collect::<Vec<_>>(),
    )
    .unwrap();
    // The character's joints 1 and 2 are the upper arm and the forearm.
    let bone_of = [upper, upper, forearm, forearm];
    let influences = character
        .influences
        .iter()
        .map(|slots| {
            slots
                .iter()
                .filter(|(_, w)| *w > 0.0)
                .map(|&(j, w)| (bone_of[j as usize], w))
                .collect()
        })
        .collect();
    let mut params = MuscleParams::surface_layer(1.1, 0.01);
    params.compliance.fiber = 5e-3; // skin stretches
    solver
        .add_muscle(MuscleDesc {
            name: "skin".into(),
            mesh: skin_mesh,
            roots: Roots::Vertices(Vec::new()),
            attachments: Vec::new(),
            targets: vec![TargetRef::Muscle(biceps)],
            params,
            maps: VertexMaps::default(),
            binding: Some(SkinBindingDesc {
                influences,
                strength: Vec::new(),
                holds_shape: false,
            }),
        })
        .unwrap();
    solver
}

/// Per skin vertex: its position minus its skinned position (the Bind goal
/// for the bones where they are now).
fn off_skinning(solver: &Solver) -> Vec<Vec3> {
    let skin = &solver.muscles()[1];
    let pose = |b: usize| solver.bones()[b].transform;
    skin.binding
        .iter()
        .map(|b| skin.x[b.vertex.index()] - b.goal(&pose))
        .collect()
}

/// Runs to frame `until` with the biceps' activation ramping 0 → 1 between
/// 1 and 1.5 s.
fn run(solver: &mut Solver, until: u32) {
    while solver.frame() < until as u64 {
        let t = solver.time();
        solver.set_activation(0, ((t - 1.0) / 0.5).clamp(0.0, 1.0));
        solver.step();
    }
}

#[test]
fn the_skin_follows_its_bones_and_bulges_over_the_muscle() {
    for method in SolverMethod::EVERY {
        let mut solver = arm(method, 2);
        let skin_vertices = solver.muscles()[1].binding.len();
        assert_eq!(
            skin_vertices,
            solver.muscles()[1].surface_count,
            "every vertex bound"
        );

        // At rest (1 s, no activation): where skinning puts it.
        run(&mut solver, 60);
        let rest = off_skinning(&solver);
        let worst_rest = rest.iter().map(|d| d.length()).fold(0.0, f32::max);

        // Flexed 90° with the biceps contracted (3.5 s): the skin over the
        // belly (the upper arm's front) is pushed out beyond skinning; the
        // back of the upper arm keeps its skinned depth and the wrist
        // follows its bone.
        run(&mut solver, 210);
        let flexed = off_skinning(&solver);
        let rest_positions = &solver.muscles()[1].mesh.positions;
        let worst = |select: &dyn Fn(Vec3) -> bool, measure: &dyn Fn(Vec3) -> f32| {
            rest_positions
                .iter()
                .zip(&flexed)
                .filter(|(p, _)| select(**p))
                .map(|(_, d)| measure(*d))
                .fold(f32::MIN, f32::max)
        };
        let over_belly = |p: Vec3| p.z > 0.9 * SKIN_RADIUS && (-0.22..-0.1).contains(&p.y);
        let outward = worst(&over_belly, &|d| d.z);
        // Behind the upper arm the skin slides along the arm towards the
        // stretched elbow (up to 5.5 mm); across it, it stays.
        let behind = |p: Vec3| p.z < -0.9 * SKIN_RADIUS && p.y > -0.2;
        let back = worst(&behind, &|d| d.z.abs());
        let wrist = worst(&|p| p.y < -1.7 * SEGMENT, &|d| d.length());
        let finite = solver
            .muscles()
            .iter()
            .all(|m| m.x.iter().all(|p| p.is_finite()));
        eprintln!(
            "{method:?}: at rest off skinning ≤ {:.2} mm; flexed and contracted: skin over the \
             biceps out {:.2} mm, back of the upper arm ≤ {:.2} mm in depth, wrist ≤ {:.2} mm off skinning",
            worst_rest * 1e3,
            outward * 1e3,
            back * 1e3,
            wrist * 1e3
        );
        assert!(finite, "{method:?}: not finite");
        assert!(
            worst_rest < 2e-3,
            "{method:?}: at rest {worst_rest} m off skinning"
        );
        assert!(
            outward >= 5e-3,
            "{method:?}: the bulge moved the skin {outward} m"
        );
        assert!(
            back < 2e-3,
            "{method:?}: the skin behind the arm moved {back} m in depth"
        );
        assert!(
            wrist < 3e-3,
            "{method:?}: the wrist's skin is {wrist} m off"
        );
    }
}

/// `analysis::skin_bulges` and `check`'s "skin bulge" figure see the same
/// bulge: none at rest (the skin is where skinning puts it), ≥ 5 mm over
/// the contracted biceps, nothing measured while no muscle is active enough.
#[test]
fn the_bulge_figure_measures_the_skin_over_the_active_muscle() {
    let mut solver = arm(SolverMethod::Sequential, 2);
    let mut metrics = RunMetrics::new(&solver, 0.002);
    let observe_to = |solver: &mut Solver, metrics: &mut RunMetrics, until: u32| {
        while solver.frame() < until as u64 {
            run(solver, solver.frame() as u32 + 1);
            metrics.observe(solver);
        }
    };
    observe_to(&mut solver, &mut metrics, 60);
    assert!(skin_bulges(&solver, 0.8).is_empty(), "no muscle is active");
    let rest = skin_bulges(&solver, 0.0);
    assert_eq!(rest.len(), 1, "the skin lies over the biceps alone");
    assert!(rest[0].max.abs() < 2e-3, "at rest: {:?}", rest[0]);
    let judged = |metrics: &RunMetrics, solver: &Solver| {
        metrics
            .verdicts(solver, &Thresholds::default(), f32::INFINITY)
            .into_iter()
            .find(|v| v.figure == "skin bulge")
            .expect("a scene with a skin has a bulge figure")
    };
    assert_eq!(judged(&metrics, &solver).pass, None, "nothing to judge yet");

    observe_to(&mut solver, &mut metrics, 210);
    let flexed = skin_bulges(&solver, 0.8);
    assert_eq!(flexed.len(), 1);
    let b = flexed[0];
    eprintln!("flexed: {b:?}");
    assert_eq!((b.skin, b.muscle, b.activation), (1, 0, 1.0));
    assert!(b.max >= 5e-3 && b.max >= b.median, "{b:?}");
    let verdict = judged(&metrics, &solver);
    assert_eq!(verdict.pass, Some(true), "{verdict:?}");
    let strict = Thresholds {
        skin_bulge: 2.0 * b.max.max(metrics.skin_bulges[0].0.max),
        ..Thresholds::default()
    };
    let failed = metrics.verdicts(&solver, &strict, f32::INFINITY);
    assert!(
        failed
            .iter()
            .any(|v| v.figure == "skin bulge" && v.pass == Some(false)),
        "twice the bulge is out of range"
    );
}

/// `check`'s "rest skin bind" figure is judged where no muscle is active:
/// at rest every bound vertex counts and is where skinning puts it; with the
/// biceps contracted, the vertices over it (meant to bulge) are reported
/// apart, and the rest of the skin still follows its bones.
#[test]
fn the_skin_bind_figure_leaves_the_active_muscles_bulge_apart() {
    let mut solver = arm(SolverMethod::Sequential, 2);
    run(&mut solver, 60);
    let bound = solver.muscles()[1].binding.len();
    let rest = skin_bind_distances(&solver, 2e-3);
    assert_eq!(rest.len(), 1);
    let r = rest[0];
    assert_eq!((r.bound, r.active_bound, r.over), (bound, 0, 0), "{r:?}");
    assert!(r.max < 2e-3, "at rest: {r:?}");

    run(&mut solver, 210);
    let f = skin_bind_distances(&solver, 2e-3)[0];
    eprintln!("flexed: {f:?}");
    assert_eq!(f.bound + f.active_bound, bound);
    // The skin tube's nearest target is the biceps everywhere (the bones
    // are thin bars inside it): the whole skin is where a muscle is active.
    assert_eq!(f.active_bound, bound, "{f:?}");
    assert!(f.active_max >= 5e-3, "the bulge is left apart: {f:?}");
    assert!(f.max <= 2e-3, "nothing judged is off: {f:?}");
}

#[test]
fn any_thread_count_gives_the_same_bits() {
    let positions = |threads| {
        let mut solver = arm(SolverMethod::Sequential, threads);
        run(&mut solver, 120);
        solver.muscles()[1].x.clone()
    };
    assert_eq!(positions(1), positions(2));
}

#[test]
fn bad_bindings_are_refused_by_name() {
    let mut solver = arm(SolverMethod::Sequential, 1);
    let mesh = MeshGenerator::Ellipsoid {
        center: Vec3::new(1.0, 0.0, 0.0),
        radii: Vec3::splat(0.02),
        segments: 8,
        stacks: 6,
    }
    .build("patch")
    .unwrap();
    let n = mesh.vertex_count();
    let mut add = |influences: Vec<Vec<(usize, f32)>>, strength: Vec<f32>| {
        solver
            .add_muscle(MuscleDesc {
                name: "patch".into(),
                mesh: mesh.clone(),
                roots: Roots::Vertices(Vec::new()),
                attachments: Vec::new(),
                targets: Vec::new(),
                params: MuscleParams::surface_layer(1.0, 0.01),
                maps: VertexMaps::default(),
                binding: Some(SkinBindingDesc {
                    influences,
                    strength,
                    holds_shape: false,
                }),
            })
            .unwrap_err()
            .to_string()
    };
    let error = add(vec![vec![(0, 1.0)]; n - 1], Vec::new());
    assert!(
        error.contains("binding.influences") && error.contains("patch"),
        "{error}"
    );
    let mut bad_bone = vec![vec![(0, 1.0)]; n];
    bad_bone[3] = vec![(7, 1.0)];
    let error = add(bad_bone, Vec::new());
    assert!(
        error.contains("binding.influences[3]") && error.contains("only 2 bones"),
        "{error}"
    );
    let mut bad_sum = vec![vec![(0, 1.0)]; n];
    bad_sum[5] = vec![(0, 0.5), (1, 0.2)];
    let error = add(bad_sum, Vec::new());
    assert!(
        error.contains("binding.influences[5]") && error.contains("sum to 1"),
        "{error}"
    );
    let mut strength = vec![1.0; n];
    strength[2] = f32::NAN;
    let error = add(vec![vec![(0, 1.0)]; n], strength);
    assert!(error.contains("binding.strength[2]"), "{error}");
}

/// A bound skin with nothing under it to slide on is held by its binding
/// alone: it sags by its weight (compliance × weight, under a millimetre),
/// it does not fall (a body without attachments or targets used to count as
/// free and had its momentum kept, which cancelled the Bind pulls).
#[test]
fn a_bound_skin_with_nothing_below_hangs_on_its_binding() {
    let mut solver = arm(SolverMethod::Sequential, 1);
    let mesh = MeshGenerator::Ellipsoid {
        center: Vec3::new(1.0, 0.0, 0.0),
        radii: Vec3::splat(0.05),
        segments: 12,
        stacks: 8,
    }
    .build("patch")
    .unwrap();
    let n = mesh.vertex_count();
    let patch = solver
        .add_muscle(MuscleDesc {
            name: "patch".into(),
            mesh,
            roots: Roots::Vertices(Vec::new()),
            attachments: Vec::new(),
            targets: Vec::new(),
            params: MuscleParams::surface_layer(1.1, 0.01),
            maps: VertexMaps::default(),
            binding: Some(SkinBindingDesc {
                influences: vec![vec![(0, 1.0)]; n],
                strength: Vec::new(),
                holds_shape: false,
            }),
        })
        .unwrap();
    let start = solver.muscles()[patch].surface_positions().to_vec();
    for _ in 0..60 {
        solver.step();
    }
    let sag = solver.muscles()[patch]
        .surface_positions()
        .iter()
        .zip(&start)
        .map(|(p, s)| p.distance(*s))
        .fold(0.0, f32::max);
    assert!(sag < 1e-3, "the bound patch moved {sag} m");
}
