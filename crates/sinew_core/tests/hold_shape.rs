//! `MuscleParams::hold_shape`: a muscle held at its two ends and by nothing
//! else (no target within reach), lying across gravity. Without it, its
//! belly hangs on its own edges and sags; held on its bones, it keeps its
//! shape — and still shortens and gains volume when activated — and moves
//! with its bones.

use sinew_core::animation::{TransformKey, TransformTrack};
use sinew_core::glam::{Quat, Vec3};
use sinew_core::mesh::primitives::MeshGenerator;
use sinew_core::muscle::{AttachmentDesc, MuscleDesc, MuscleParams, Roots, VertexMaps};
use sinew_core::{Solver, SolverMethod, SolverSettings};

const CENTER: Vec3 = Vec3::new(0.0, 0.0, 0.0);
const RADII: Vec3 = Vec3::new(0.12, 0.02, 0.02);

/// A 24 cm spindle along X from one bone to another, the second turning
/// 60° about Z (the elbow) between 1 and 2 s when `flex`.
fn spindle(hold_shape: bool, flex: bool, method: SolverMethod) -> Solver {
    let settings = SolverSettings {
        method,
        threads: 2,
        gravity: Vec3::new(0.0, -9.81, 0.0),
        ..Default::default()
    };
    let mut solver = Solver::new(settings).unwrap();
    let still = |at: Vec3| TransformTrack {
        keys: vec![TransformKey {
            time: 0.0,
            translation: at,
            rotation: Quat::IDENTITY,
        }],
        ..Default::default()
    };
    let upper = solver.add_bone("upper", still(Vec3::ZERO), None);
    let mut track = still(Vec3::ZERO);
    if flex {
        let key = |time: f32, angle: f32| TransformKey {
            time,
            translation: Vec3::ZERO,
            rotation: Quat::from_rotation_z(angle.to_radians()),
        };
        track.keys = vec![key(0.0, 0.0), key(1.0, 0.0), key(2.0, 60.0)];
    }
    let lower = solver.add_bone("lower", track, None);
    let mesh = MeshGenerator::Ellipsoid {
        center: CENTER,
        radii: RADII,
        segments: 16,
        stacks: 24,
    }
    .build("spindle")
    .unwrap();
    let tip = |bone: usize, x: f32| AttachmentDesc {
        bone: Some(bone),
        point: Some(CENTER + Vec3::new(x, 0.0, 0.0)),
        radius: 0.015,
        ..Default::default()
    };
    solver
        .add_muscle(MuscleDesc {
            name: "spindle".into(),
            mesh,
            roots: Roots::Attachments,
            attachments: vec![tip(upper, -RADII.x), tip(lower, RADII.x)],
            targets: Vec::new(),
            params: MuscleParams {
                hold_shape,
                ..Default::default()
            },
            maps: VertexMaps::default(),
            binding: None,
        })
        .unwrap();
    solver
}

/// Largest distance of a surface vertex from its rest position carried by
/// its bones (its binding's goal; the rest position itself when unbound:
/// the first bone does not move).
fn off_rest(solver: &Solver) -> f32 {
    let m = &solver.muscles()[0];
    let pose = |b: usize| solver.bones()[b].transform;
    (0..m.surface_count)
        .map(|v| {
            let goal = m
                .binding
                .iter()
                .find(|b| b.vertex.index() == v)
                .map_or(m.rest[v], |b| b.goal(&pose));
            m.x[v].distance(goal)
        })
        .fold(0.0, f32::max)
}

/// Largest edge length / rest length.
fn max_strain(solver: &Solver) -> f32 {
    let m = &solver.muscles()[0];
    m.mesh
        .edges
        .iter()
        .map(|&[a, b]| {
            let (a, b) = (a as usize, b as usize);
            m.x[a].distance(m.x[b]) / m.rest[a].distance(m.rest[b])
        })
        .fold(0.0, f32::max)
}

#[test]
fn a_muscle_held_only_at_its_ends_sags_unless_it_holds_its_shape() {
    let mut free = spindle(false, false, SolverMethod::Sequential);
    let mut held = spindle(true, false, SolverMethod::Sequential);
    assert!(free.muscles()[0].binding.is_empty());
    assert_eq!(
        held.muscles()[0].binding.len(),
        held.muscles()[0].surface_count,
        "every surface vertex held"
    );
    assert!(
        !held.muscles()[0].is_skin(),
        "a muscle holding its shape is no skin"
    );
    for _ in 0..120 {
        free.step();
        held.step();
    }
    let (sag_free, sag_held) = (off_rest(&free), off_rest(&held));
    let (strain_free, strain_held) = (max_strain(&free), max_strain(&held));
    eprintln!(
        "after 2 s: free sags {:.2} mm (edge strain ≤ {strain_free:.3}), held {:.2} mm (≤ {strain_held:.3})",
        sag_free * 1e3,
        sag_held * 1e3
    );
    assert!(sag_free > 5e-3, "the free muscle hangs: {sag_free} m");
    assert!(
        sag_held < 1e-3,
        "the held muscle keeps its shape: {sag_held} m"
    );
    assert!(strain_held < 1.05, "{strain_held}");
}

#[test]
fn a_muscle_holding_its_shape_still_contracts_and_follows_its_bones() {
    for method in SolverMethod::EVERY {
        let mut solver = spindle(true, true, method);
        let rest_volume = solver.muscles()[0].rest_volume();
        while solver.time() < 3.0 {
            let a = ((solver.time() - 2.0) / 0.5).clamp(0.0, 1.0);
            solver.set_activation(0, a);
            solver.step();
        }
        let m = &solver.muscles()[0];
        let gain = m.params.volume.gain * m.params.volume.activation_gain;
        let ratio = m.volume() / rest_volume;
        let finite = m.x.iter().all(|p| p.is_finite());
        // Flexed 60° and fully active: the belly is off its rest shape by
        // what the bend and the contraction move it, not by a sag, and it
        // reached its active volume.
        eprintln!(
            "{method:?}: volume ×{ratio:.3} (gain {gain:.2}), off the bones' rest shape ≤ {:.1} mm",
            off_rest(&solver) * 1e3
        );
        assert!(finite, "{method:?}");
        assert!(
            (ratio - f64::from(gain)).abs() < 0.05 * f64::from(gain),
            "{method:?}: volume ×{ratio} for a gain of {gain}"
        );
        assert!(
            off_rest(&solver) < 0.03,
            "{method:?}: {}",
            off_rest(&solver)
        );
    }
}

/// The hold is a relaxed muscle's: with `hold_release` 0.1 its Bind
/// compliance is divided by `max(1 − a, 0.1)`, so that a
/// contracting muscle slides and bulges between its bones as its fibres
/// and volume make it (T5's biceps: `anatomy_scenes.rs`), and once it
/// relaxes the hold brings it back to its rest shape on its bones.
#[test]
fn a_contracting_muscle_is_released_by_its_hold_and_held_again_when_relaxed() {
    for method in SolverMethod::EVERY {
        let mut solver = spindle(true, false, method);
        solver.muscle_mut(0).params.hold_release = 0.1;
        let base = solver.muscles()[0].params.compliance.bind;
        let compliances = |solver: &Solver| solver.muscles()[0].constraints.bind.compliance.clone();
        assert!(compliances(&solver).iter().all(|&c| c == base));
        while solver.time() < 2.0 {
            let a = ((solver.time() - 0.5) / 0.5).clamp(0.0, 1.0);
            solver.set_activation(0, a);
            solver.step();
        }
        let released = base / 0.1;
        assert!(
            compliances(&solver)
                .iter()
                .all(|&c| (c - released).abs() < 1e-6 * released),
            "{method:?}: at full activation the hold keeps a tenth of its pull"
        );
        while solver.time() < 4.0 {
            solver.set_activation(0, 0.0);
            solver.step();
        }
        assert!(compliances(&solver).iter().all(|&c| c == base));
        eprintln!(
            "{method:?}: relaxed, {:.2} mm off its rest shape",
            off_rest(&solver) * 1e3
        );
        assert!(
            off_rest(&solver) < 0.002,
            "{method:?}: relaxed, {} mm off its rest shape",
            off_rest(&solver) * 1e3
        );
    }
}
