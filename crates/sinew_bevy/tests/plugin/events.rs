//! The plug-in tells the app what happened: a muscle built, a build that
//! failed (with a typed error), settings rejected — as entity events for
//! observers, as messages, and in the panel's log; what the panel's Reset
//! does to a hand-built muscle; and a mesh entity made a bone (entities
//! of one mesh sharing one geometry).

use crate::common;

use bevy::prelude::*;
use sinew_bevy::prelude::*;
use sinew_core::glam::Vec3 as CoreVec3;
use sinew_core::mesh::primitives::thesis_oval;
use sinew_core::muscle::{MuscleParams, Roots};
use std::sync::{Arc, Mutex};

use common::app;

#[test]
fn a_built_muscle_is_announced_to_observers_and_in_the_log() {
    let mut app = app();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let seen_by_observer = seen.clone();
    app.add_observer(move |built: On<MuscleBuilt>| {
        seen_by_observer.lock().unwrap().push(built.entity);
    });
    let bone = app.world_mut().spawn(SinewBone::new("hook")).id();
    let muscle = app
        .world_mut()
        .spawn((Name::new("oval"), common::oval_on(bone)))
        .id();
    common::update_until(&mut app, |app| {
        app.world().get::<MuscleState>(muscle).is_some()
    });
    app.update();
    assert_eq!(*seen.lock().unwrap(), vec![muscle]);
    let log = app.world().resource::<SinewLog>();
    assert!(
        log.lines.iter().any(|l| l == "built oval"),
        "{:?}",
        log.lines
    );
}

#[test]
fn a_failed_build_is_a_typed_error_for_observers_and_the_log() {
    let mut app = app();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let seen_by_observer = seen.clone();
    app.add_observer(move |failed: On<MuscleBuildFailed>| {
        let is_mesh = matches!(*failed.error, MuscleBuildError::Mesh(_));
        seen_by_observer
            .lock()
            .unwrap()
            .push((failed.entity, is_mesh));
    });
    // A muscle whose parameters the core refuses: a negative compliance.
    let mesh = thesis_oval(CoreVec3::ZERO).build("oval").unwrap();
    let mut params = MuscleParams::default();
    params.compliance.fiber = -1.0;
    let refused = app
        .world_mut()
        .spawn(MuscleBuilder::new("refused", MuscleSource::Mesh(mesh)).params(params))
        .id();
    let missing = app
        .world_mut()
        .spawn(MuscleBuilder::new(
            "missing",
            MuscleSource::File("no/such/file.obj".into(), Default::default()),
        ))
        .id();
    common::update_until(&mut app, |app| {
        [refused, missing]
            .iter()
            .all(|&e| app.world().get::<BuildFailed>(e).is_some())
    });
    app.update();
    let failed = app.world().get::<BuildFailed>(refused).unwrap();
    assert!(
        matches!(
            *failed.0,
            MuscleBuildError::Build(sinew_core::BuildError::InvalidParameter { .. })
        ),
        "{}",
        failed.0
    );
    let mut seen = seen.lock().unwrap().clone();
    seen.sort();
    let mut expected = vec![(refused, false), (missing, true)];
    expected.sort();
    assert_eq!(seen, expected);
    let log = app.world().resource::<SinewLog>();
    assert_eq!(
        log.lines
            .iter()
            .filter(|l| l.starts_with("build failed"))
            .count(),
        2
    );
}

#[test]
fn rejected_settings_are_announced_once() {
    let mut app = app();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let seen_by_observer = seen.clone();
    app.add_observer(move |rejected: On<SettingsRejected>| {
        seen_by_observer
            .lock()
            .unwrap()
            .push(rejected.error.to_string());
    });
    app.update();
    app.world_mut().resource_mut::<SinewSettings>().dt = f32::NAN;
    for _ in 0..5 {
        app.update();
    }
    let seen = seen.lock().unwrap().clone();
    assert_eq!(seen.len(), 1, "{seen:?}");
    assert!(seen[0].contains("dt"), "{}", seen[0]);
    let log = app.world().resource::<SinewLog>();
    assert_eq!(
        log.lines
            .iter()
            .filter(|l| l.starts_with("settings rejected"))
            .count(),
        1
    );
    // The simulation went on with the last valid settings.
    assert_eq!(app.world().resource::<SinewClock>().frame, 6);
}

#[test]
fn a_muscle_that_blows_up_is_put_back_and_announced() {
    let mut app = app();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let seen_by_observer = seen.clone();
    app.add_observer(move |faulted: On<MuscleFaulted>| {
        seen_by_observer
            .lock()
            .unwrap()
            .push((faulted.entity, faulted.fault.kind));
    });
    let bone = app.world_mut().spawn(SinewBone::new("hook")).id();
    let muscle = app
        .world_mut()
        .spawn((Name::new("oval"), common::oval_on(bone)))
        .id();
    common::update_until(&mut app, |app| {
        app.world().get::<MuscleState>(muscle).is_some()
    });
    for _ in 0..3 {
        app.update();
    }
    let good = app
        .world()
        .get::<MuscleState>(muscle)
        .unwrap()
        .muscle
        .x
        .clone();
    app.world_mut()
        .get_mut::<MuscleState>(muscle)
        .unwrap()
        .muscle
        .x[5] = CoreVec3::NAN;
    app.update();
    let seen = seen.lock().unwrap().clone();
    assert_eq!(seen, [(muscle, sinew_core::solver::FaultKind::NonFinite)]);
    let x = &app.world().get::<MuscleState>(muscle).unwrap().muscle.x;
    assert_eq!(*x, good, "put back to its last good frame");
    let log = app.world().resource::<SinewLog>();
    assert!(
        log.lines
            .iter()
            .any(|l| l.contains("muscle 'oval' went non-finite")),
        "{:?}",
        log.lines
    );
}

#[test]
fn reset_puts_a_hand_built_muscle_back_as_it_was_built() {
    let mut app = app();
    *app.world_mut().resource_mut::<SimulationState>() = SimulationState::Paused;
    let bone = app.world_mut().spawn(SinewBone::new("hook")).id();
    let muscle = app.world_mut().spawn(common::oval_on(bone)).id();
    common::update_until(&mut app, |app| {
        app.world().get::<MuscleState>(muscle).is_some()
    });
    let positions = |app: &App| {
        app.world()
            .get::<MuscleState>(muscle)
            .unwrap()
            .muscle
            .x
            .clone()
    };
    let built = positions(&app);
    // Contract it for half a second: it deforms.
    app.world_mut()
        .get_mut::<Muscle>(muscle)
        .unwrap()
        .activation = 1.0;
    *app.world_mut().resource_mut::<SimulationState>() = SimulationState::Playing;
    for _ in 0..30 {
        app.update();
    }
    let moved = positions(&app)
        .iter()
        .zip(&built)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f32::max);
    assert!(moved > 1e-3, "the muscle must deform ({moved} m)");
    // Reset while paused: back to the built positions, bit for bit.
    *app.world_mut().resource_mut::<SimulationState>() = SimulationState::Paused;
    app.world_mut().write_message(ResetSimulation);
    app.update();
    assert!(positions(&app) == built, "reset left the muscle deformed");
    assert_eq!(app.world().resource::<SinewClock>().frame, 0);
    // Playing again steps it from there.
    *app.world_mut().resource_mut::<SimulationState>() = SimulationState::Playing;
    app.update();
    assert!(positions(&app).iter().all(|p| p.is_finite()));
}

/// [`app`] with mesh assets, for entities made bones from their meshes.
#[cfg(feature = "render")]
fn app_with_meshes() -> App {
    let mut app = app();
    app.add_plugins(bevy::asset::AssetPlugin::default())
        .init_asset::<Mesh>();
    app
}

#[cfg(feature = "render")]
#[test]
fn any_mesh_entity_becomes_a_bone_a_muscle_slides_on() {
    let mut app = app_with_meshes();
    let ball = app
        .world_mut()
        .resource_mut::<Assets<Mesh>>()
        .add(Sphere::new(0.02).mesh().ico(3).unwrap());
    // A ball just under the oval (the oval is 2.5 cm thick): 1 mm gap.
    let bone = app
        .world_mut()
        .spawn((
            Name::new("ball"),
            Mesh3d(ball),
            TargetFromMesh,
            Transform::from_xyz(0.0, -0.0125 - 0.021, 0.0),
        ))
        .id();
    let mesh = thesis_oval(CoreVec3::ZERO).build("oval").unwrap();
    let muscle = app
        .world_mut()
        .spawn(
            MuscleBuilder::new("oval", MuscleSource::Mesh(mesh))
                .roots(Roots::LongestAxisTips)
                .attach(MuscleAttachment::region(
                    bone,
                    Vec3::new(-0.03, 0.0, 0.0),
                    0.005,
                ))
                .target(bone),
        )
        .id();
    common::update_until(&mut app, |app| {
        app.world().get::<MuscleState>(muscle).is_some()
    });
    app.update();
    assert!(app.world().get::<SinewBone>(bone).is_some());
    let target = &app
        .world()
        .get::<BoneTarget>(bone)
        .expect("a bone target")
        .0;
    assert!(
        target.triangles().len() > 100,
        "{} triangles",
        target.triangles().len()
    );
    let state = app.world().get::<MuscleState>(muscle).unwrap();
    let sliding = &state.muscle.constraints.sliding;
    let touching = sliding.connected.iter().filter(|&&c| c).count();
    assert!(touching > 0, "no oval vertex slides on the ball");
}

/// Entities of one mesh asset share one bone geometry, and one of another
/// mesh does not. A mesh edited in place gets a target of its own (its new
/// surface), which later entities of that mesh share.
#[cfg(feature = "render")]
#[test]
fn mesh_entities_of_one_asset_share_one_bone_geometry() {
    use bevy::mesh::VertexAttributeValues;
    let mut app = app_with_meshes();
    let mut meshes = app.world_mut().resource_mut::<Assets<Mesh>>();
    let ball = meshes.add(Sphere::new(0.02).mesh().ico(3).unwrap());
    let cube = meshes.add(Cuboid::new(0.02, 0.03, 0.04).mesh().build());
    let spawn = |app: &mut App, mesh: &Handle<Mesh>, name: &str| {
        let bone = (Name::new(name.to_string()), Mesh3d(mesh.clone()));
        app.world_mut()
            .spawn((bone, TargetFromMesh, Transform::default()))
            .id()
    };
    let target = |app: &App, e: Entity| app.world().get::<BoneTarget>(e).map(|t| t.0.clone());
    let built = |app: &mut App, entities: &[Entity]| {
        common::update_until(app, |app| {
            entities.iter().all(|&e| target(app, e).is_some())
        });
        let targets = entities.iter().map(|&e| target(app, e).unwrap());
        targets.collect::<Vec<_>>()
    };
    let entities = [
        spawn(&mut app, &ball, "a"),
        spawn(&mut app, &ball, "b"),
        spawn(&mut app, &cube, "c"),
    ];
    let [a, b, c] = &built(&mut app, &entities)[..] else {
        unreachable!()
    };
    assert!(a.shares_geometry_with(b));
    assert!(!a.shares_geometry_with(c));
    assert_eq!((a.name.as_str(), b.name.as_str()), ("a", "b"));
    // The ball twice as large, in place.
    {
        let mut meshes = app.world_mut().resource_mut::<Assets<Mesh>>();
        let mut mesh = meshes.get_mut(&ball).unwrap();
        let Some(VertexAttributeValues::Float32x3(positions)) =
            mesh.attribute_mut(Mesh::ATTRIBUTE_POSITION)
        else {
            panic!("the ball has positions");
        };
        positions.iter_mut().flatten().for_each(|x| *x *= 2.0);
    }
    let entities = [spawn(&mut app, &ball, "d"), spawn(&mut app, &ball, "e")];
    let [d, e] = &built(&mut app, &entities)[..] else {
        unreachable!()
    };
    assert!(!d.shares_geometry_with(a));
    assert!(d.shares_geometry_with(e));
    let (old, new) = (a.positions(), d.positions());
    assert_eq!(old.len(), new.len());
    assert!(old.iter().zip(new).all(|(o, n)| *n == 2.0 * *o));
}
