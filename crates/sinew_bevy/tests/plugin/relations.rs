//! Attachments and connections are entities related to muscles and bones:
//! attaching, detaching and re-targeting at run time, sliding on a target
//! through a connection entity, bad attachments refused with a typed error,
//! constraint sets as a queryable component, and every relation type
//! registered for reflection.

use crate::common;

use bevy::prelude::*;
use sinew_bevy::prelude::*;
use sinew_core::BuildError;
use sinew_core::glam::Vec3 as CoreVec3;
use sinew_core::mesh::primitives::thesis_oval;
use sinew_core::muscle::{ConstraintKind, Roots};
use sinew_core::scene::{BoneShape, builtin};
use std::f32::consts::FRAC_PI_2;
use std::path::Path;
use std::sync::{Arc, Mutex};

use common::update_until;

/// The plug-in's headless app with gravity.
fn app() -> App {
    let mut app = common::app();
    app.world_mut().resource_mut::<SinewSettings>().gravity = Vec3::new(0.0, -9.81, 0.0);
    app
}

/// The lowest surface vertex of `muscle` (m).
fn lowest(app: &App, muscle: Entity) -> f32 {
    let state = app.world().get::<MuscleState>(muscle).unwrap();
    state
        .surface_positions()
        .iter()
        .map(|p| p.y)
        .fold(f32::INFINITY, f32::min)
}

/// P1's oval hand-built with no attachment at all (it falls).
fn free_oval(app: &mut App) -> Entity {
    let mesh = thesis_oval(CoreVec3::ZERO).build("oval").unwrap();
    let builder =
        MuscleBuilder::new("oval", MuscleSource::Mesh(mesh)).roots(Roots::LongestAxisTips);
    let muscle = app.world_mut().spawn((Name::new("oval"), builder)).id();
    update_until(app, |app| app.world().get::<MuscleState>(muscle).is_some());
    muscle
}

/// A bone called "hook" and P1's oval held by it (vertex 0), built.
fn oval_on_a_hook(app: &mut App) -> (Entity, Entity) {
    let bone = app.world_mut().spawn(SinewBone::new("hook")).id();
    let muscle = app.world_mut().spawn(common::oval_on(bone)).id();
    update_until(app, |app| app.world().get::<MuscleState>(muscle).is_some());
    (bone, muscle)
}

/// Collects what observers see of `E`.
fn observed<E: EntityEvent + Clone>(app: &mut App) -> Arc<Mutex<Vec<E>>> {
    let seen = Arc::new(Mutex::new(Vec::new()));
    let sink = seen.clone();
    app.add_observer(move |event: On<E>| sink.lock().unwrap().push(event.event().clone()));
    seen
}

#[test]
fn an_attachment_spawned_at_run_time_holds_a_falling_muscle() {
    let mut app = app();
    let attached = observed::<MuscleAttached>(&mut app);
    let bone = app.world_mut().spawn(SinewBone::new("hook")).id();
    let muscle = free_oval(&mut app);
    for _ in 0..10 {
        app.update();
    }
    let falling = lowest(&app, muscle);
    assert!(falling < -0.0125 - 0.001, "it falls: lowest {falling}");
    // Hold the vertices within 1 cm of its +X tip (where it is now).
    let state = app.world().get::<MuscleState>(muscle).unwrap();
    let tip = state
        .surface_positions()
        .iter()
        .copied()
        .max_by(|a, b| a.x.total_cmp(&b.x))
        .unwrap();
    let attachment = app
        .world_mut()
        .spawn(AttachmentRegion::near(tip, 0.01).on(muscle, bone))
        .id();
    app.update();
    let held: Vec<u32> = app
        .world()
        .get::<HeldVertices>(attachment)
        .unwrap()
        .vertices()
        .collect();
    assert!(held.len() > 1, "a region, not one vertex: {held:?}");
    assert_eq!(
        app.world()
            .get::<MuscleState>(muscle)
            .unwrap()
            .muscle
            .attachments
            .len(),
        held.len()
    );
    assert_eq!(
        *attached.lock().unwrap(),
        vec![MuscleAttached {
            entity: muscle,
            attachment,
            bone: Some(bone)
        }]
    );
    for _ in 0..60 {
        app.update();
    }
    // The held vertices stayed where they were attached (the bone is still).
    let state = app.world().get::<MuscleState>(muscle).unwrap();
    let x = state.surface_positions();
    let moved = held
        .iter()
        .map(|&v| x[v as usize].distance(tip))
        .fold(0.0, f32::max);
    assert!(
        moved < 0.0105,
        "held vertices drifted {moved} m from the tip region"
    );
    assert_eq!(
        app.world()
            .get::<HeldAttachments>(bone)
            .unwrap()
            .iter()
            .collect::<Vec<_>>(),
        vec![attachment]
    );
}

#[test]
fn despawning_an_attachment_detaches_the_muscle() {
    let mut app = app();
    let detached = observed::<MuscleDetached>(&mut app);
    let (bone, muscle) = oval_on_a_hook(&mut app);
    for _ in 0..30 {
        app.update();
    }
    let hanging = lowest(&app, muscle);
    let attachments: Vec<Entity> = app
        .world()
        .get::<Attachments>(muscle)
        .unwrap()
        .iter()
        .collect();
    assert_eq!(attachments.len(), 1, "one attachment entity per bone");
    app.world_mut().entity_mut(attachments[0]).despawn();
    for _ in 0..30 {
        app.update();
    }
    let state = app.world().get::<MuscleState>(muscle).unwrap();
    assert!(state.muscle.attachments.is_empty());
    assert!(
        state.muscle.w.iter().all(|&w| w > 0.0),
        "no particle stays pinned"
    );
    let fallen = lowest(&app, muscle);
    assert!(
        fallen < hanging - 0.05,
        "free, it falls: lowest {hanging} → {fallen}"
    );
    assert_eq!(
        *detached.lock().unwrap(),
        vec![MuscleDetached {
            entity: muscle,
            attachment: attachments[0],
            bone: Some(bone)
        }]
    );
    assert!(
        app.world()
            .resource::<SinewLog>()
            .lines
            .iter()
            .any(|l| l.contains("detached from")),
        "the panel's log says so"
    );
}

#[test]
fn despawning_a_bone_detaches_what_it_held() {
    let mut app = app();
    let (bone, muscle) = oval_on_a_hook(&mut app);
    app.update();
    app.world_mut().entity_mut(bone).despawn();
    app.update();
    assert!(app.world().get::<Attachments>(muscle).is_none());
    let state = app.world().get::<MuscleState>(muscle).unwrap();
    assert!(state.muscle.attachments.is_empty());
    assert!(state.muscle.x.iter().all(|p| p.is_finite()));
}

#[test]
fn a_re_targeted_attachment_follows_its_new_bone() {
    let mut app = app();
    let still = app.world_mut().spawn(SinewBone::new("still")).id();
    let moving = app.world_mut().spawn(SinewBone::new("moving")).id();
    let muscle = app.world_mut().spawn(common::oval_on(still)).id();
    update_until(&mut app, |app| {
        app.world().get::<MuscleState>(muscle).is_some()
    });
    app.update();
    let attachment = app
        .world()
        .get::<Attachments>(muscle)
        .unwrap()
        .iter()
        .next()
        .unwrap();
    app.world_mut()
        .entity_mut(attachment)
        .insert(AttachedTo(moving));
    app.update();
    let start = app.world().get::<MuscleState>(muscle).unwrap().muscle.x[0];
    // The new bone rises 1 mm a frame; vertex 0 rises with it.
    for frame in 1..=30 {
        app.world_mut()
            .get_mut::<Transform>(moving)
            .unwrap()
            .translation
            .y = 0.001 * frame as f32;
        app.update();
    }
    let end = app.world().get::<MuscleState>(muscle).unwrap().muscle.x[0];
    assert!(
        ((end.y - start.y) - 0.030).abs() < 1e-4,
        "vertex 0 rose {} m with the bone's 0.030 m",
        end.y - start.y
    );
    assert!(app.world().get::<HeldAttachments>(still).is_none());
}

#[test]
fn connections_are_entities_a_muscle_slides_through() {
    // P1's oval with no attachments, its ground raised to 2 mm under it
    // (within Sliding's reach).
    let mut scene = builtin("P1").unwrap();
    scene.muscles[0].attachments.clear();
    scene.muscles[0].roots = Roots::LongestAxisTips;
    let ground_y = -0.0145;
    let Some(BoneShape::Plane { center, .. }) = &mut scene.bones[0].shape else {
        panic!("P1's ground is a plane");
    };
    center.y = ground_y;
    let mut app = app();
    let root = app
        .world_mut()
        .spawn(SinewSceneRoot::Built(Arc::new(
            SinewScene::build(scene, Path::new(".")).unwrap(),
        )))
        .id();
    app.update();
    let spawned = app.world().get::<SpawnedScene>(root).unwrap().clone();
    let (muscle, ground) = (spawned.muscles[0], spawned.bones[0]);
    for _ in 0..60 {
        app.update();
    }
    // Held by it (a second of free fall is 4.9 m), sunk a little into it
    // at the default compliances.
    let resting = lowest(&app, muscle);
    assert!(resting > ground_y - 0.02, "held by the ground: {resting}");
    let sets = *app.world().get::<ConstraintSets>(muscle).unwrap();
    let surface = app
        .world()
        .get::<MuscleState>(muscle)
        .unwrap()
        .muscle
        .surface_count;
    assert_eq!(sets.sliding.count, surface, "one Sliding per vertex");
    assert!(sets.sliding.active > 0);
    // Remove the connection entity: the muscle falls through.
    let connection = app
        .world()
        .get::<Connections>(muscle)
        .unwrap()
        .iter()
        .next()
        .unwrap();
    assert_eq!(
        app.world().get::<ConnectsTo>(connection),
        Some(&ConnectsTo(ground))
    );
    app.world_mut().entity_mut(connection).despawn();
    for _ in 0..30 {
        app.update();
    }
    assert!(lowest(&app, muscle) < ground_y - 0.5, "nothing holds it");
    assert_eq!(
        app.world()
            .get::<ConstraintSets>(muscle)
            .unwrap()
            .sliding
            .active,
        0,
        "no Sliding acts without a target"
    );
}

#[test]
fn bad_attachments_are_refused_with_a_typed_error() {
    let mut app = app();
    let refused = observed::<AttachmentRejected>(&mut app);
    let not_a_bone = app.world_mut().spawn(Transform::default()).id();
    let (bone, muscle) = oval_on_a_hook(&mut app);
    app.update();
    let out_of_range = app
        .world_mut()
        .spawn(AttachmentRegion::Vertices(vec![7, 100_000]).on(muscle, bone))
        .id();
    let on_a_non_bone = app
        .world_mut()
        .spawn(AttachmentRegion::Vertices(vec![7]).on(muscle, not_a_bone))
        .id();
    let bad_radius = app
        .world_mut()
        .spawn(AttachmentRegion::near(Vec3::ZERO, f32::NAN).in_world(muscle))
        .id();
    for _ in 0..5 {
        app.update();
    }
    let refused = refused.lock().unwrap();
    assert_eq!(refused.len(), 3, "each reported once: {refused:?}");
    let error_of = |e: Entity| {
        refused
            .iter()
            .find(|r| r.attachment == e)
            .unwrap()
            .error
            .clone()
    };
    assert!(matches!(
        *error_of(out_of_range),
        MuscleBuildError::Build(BuildError::AttachmentVertexOutOfRange {
            vertex: 100_000,
            ..
        })
    ));
    assert!(matches!(
        *error_of(on_a_non_bone),
        MuscleBuildError::MissingBone { bone, .. } if bone == not_a_bone
    ));
    assert!(matches!(
        *error_of(bad_radius),
        MuscleBuildError::Build(BuildError::InvalidParameter { .. })
    ));
    // The good attachment still holds; nothing else does.
    let state = app.world().get::<MuscleState>(muscle).unwrap();
    assert_eq!(state.muscle.attachments.len(), 1);
    assert!(state.muscle.x.iter().all(|p| p.is_finite()));
}

#[test]
fn constraint_sets_are_a_component_that_follows_edits() {
    let mut app = app();
    let (_, muscle) = oval_on_a_hook(&mut app);
    app.update();
    let state = app.world().get::<MuscleState>(muscle).unwrap();
    let counts = state.muscle.counts();
    let sets = *app.world().get::<ConstraintSets>(muscle).unwrap();
    for kind in ConstraintKind::CANONICAL_ORDER {
        assert_eq!(sets.get(kind).count, counts.get(kind), "{kind:?}");
    }
    assert_eq!(sets.attach.count, 1);
    assert!(sets.fiber.count > 0 && sets.volume.count == 1);
    app.world_mut()
        .get_mut::<Muscle>(muscle)
        .unwrap()
        .compliance
        .fiber = 3e-5;
    app.update();
    let sets = app.world().get::<ConstraintSets>(muscle).unwrap();
    assert_eq!(sets.fiber.compliance, 3e-5);
}

#[test]
fn weights_contraction_and_rest_activation_are_live() {
    // P1 (linked to its ground: Soft and Hard tie every vertex to it).
    let mut app = app();
    let root = app
        .world_mut()
        .spawn(SinewSceneRoot::Built(Arc::new(
            SinewScene::build(builtin("P1").unwrap(), Path::new(".")).unwrap(),
        )))
        .id();
    app.update();
    app.update();
    let muscle = app.world().get::<SpawnedScene>(root).unwrap().muscles[0];
    assert!(
        app.world()
            .get::<ConstraintSets>(muscle)
            .unwrap()
            .hard
            .active
            > 0
    );
    {
        let mut live = app.world_mut().get_mut::<Muscle>(muscle).unwrap();
        live.weights.hard = 0.0;
        live.max_contraction = 0.5;
        live.rest_activation = 0.2;
        live.hold_release = 0.3;
    }
    app.update();
    let sets = app.world().get::<ConstraintSets>(muscle).unwrap();
    assert_eq!(sets.hard.active, 0, "weight 0 switches Hard off");
    let params = &app
        .world()
        .get::<MuscleState>(muscle)
        .unwrap()
        .muscle
        .params;
    assert_eq!((params.max_contraction, params.rest_activation), (0.5, 0.2));
    assert_eq!(params.hold_release, 0.3);
    assert_eq!(params.weights.hard, 0.0);
    // A value the core refuses keeps the last valid ones.
    app.world_mut()
        .get_mut::<Muscle>(muscle)
        .unwrap()
        .max_contraction = 2.0;
    app.update();
    let params = &app
        .world()
        .get::<MuscleState>(muscle)
        .unwrap()
        .muscle
        .params;
    assert_eq!(params.max_contraction, 0.5);
}

#[test]
fn relations_and_sets_are_registered_for_reflection() {
    let mut app = app();
    app.update();
    let registry = app.world().resource::<AppTypeRegistry>().read();
    for name in [
        "AttachmentOf",
        "Attachments",
        "AttachedTo",
        "HeldAttachments",
        "AttachmentRegion",
        "ConnectionOf",
        "Connections",
        "ConnectsTo",
        "ConnectedFrom",
        "ConstraintSets",
        "Muscle",
        "SinewBone",
    ] {
        assert!(
            registry.get_with_short_type_path(name).is_some(),
            "{name} is not registered"
        );
    }
}

#[test]
fn the_minimal_example_slides_its_muscle_on_the_bone() {
    // What `examples/minimal.rs` spawns, headless.
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/meshes/myoarm");
    let mut app = app();
    let humerus = BoneTarget::load(assets.join("humerus_r.obj")).unwrap();
    let at = Transform::from_xyz(-0.170, 0.474, -0.0995)
        .with_rotation(Quat::from_rotation_y(-FRAC_PI_2));
    let bone = app
        .world_mut()
        .spawn((SinewBone::new("humerus"), humerus, at))
        .id();
    let tip = Vec3::new(-0.166, 0.300, -0.093);
    let muscle = app
        .world_mut()
        .spawn(
            MuscleBuilder::new("brachialis", MuscleSource::file(assets.join("BRA.obj")))
                .roots(Roots::LongestAxisTips)
                .attach(MuscleAttachment::region(bone, tip, 0.018))
                .target(bone),
        )
        .id();
    update_until(&mut app, |app| {
        app.world().get::<MuscleState>(muscle).is_some()
    });
    let rest = app
        .world()
        .get::<MuscleState>(muscle)
        .unwrap()
        .muscle
        .rest
        .clone();
    for _ in 0..120 {
        app.update();
    }
    let state = app.world().get::<MuscleState>(muscle).unwrap();
    assert!(state.muscle.x.iter().all(|p| p.is_finite()));
    let sets = app.world().get::<ConstraintSets>(muscle).unwrap();
    assert!(
        sets.attach.count > 1,
        "held by a region: {}",
        sets.attach.count
    );
    assert!(
        sets.sliding.active > 0 && sets.hard.active > 0,
        "connected to the bone: {sets:?}"
    );
    // The tendon stays put; the belly hangs, held against the bone.
    let moved = |v: usize| state.muscle.x[v].distance(rest[v]);
    let tendon = state
        .muscle
        .attachments
        .iter()
        .map(|a| moved(a.vertex.index()));
    assert!(tendon.fold(0.0, f32::max) < 1e-4);
    let sag = (0..state.muscle.surface_count)
        .map(moved)
        .fold(0.0, f32::max);
    assert!(sag < 0.05, "the bone holds the belly: largest move {sag} m");
}
