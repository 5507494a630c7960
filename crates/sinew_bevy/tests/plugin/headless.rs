//! The Bevy driver, headless (`MinimalPlugins`): it agrees with the plain
//! driver bit for bit, and activation, bones moved by systems, method
//! switches and despawns behave.

use crate::common;

use bevy::prelude::*;
use sinew_bevy::prelude::*;
use sinew_core::glam::Vec3 as CoreVec3;
use sinew_core::scene::{Scene, builtin};
use sinew_core::{Solver, SweepSchedule};
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn asset(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets")
        .join(path)
}

use common::app;

fn spawn_scene(app: &mut App, scene: SinewScene) -> Entity {
    app.world_mut()
        .spawn(SinewSceneRoot::Built(Arc::new(scene)))
        .id()
}

fn spawned(app: &App, root: Entity) -> SpawnedScene {
    app.world().get::<SpawnedScene>(root).unwrap().clone()
}

fn positions(app: &App, muscle: Entity) -> Vec<CoreVec3> {
    app.world()
        .get::<MuscleState>(muscle)
        .unwrap()
        .muscle
        .x
        .clone()
}

fn builtin_scene(name: &str) -> SinewScene {
    SinewScene::build(builtin(name).unwrap(), Path::new(".")).unwrap()
}

/// The plain driver and an app with the same scene spawned, not stepped yet.
fn both_drivers(scene: Scene, base_dir: &Path) -> (Solver, App, Entity) {
    let plain = scene.instantiate(base_dir).unwrap();
    let mut app = app();
    let root = spawn_scene(&mut app, SinewScene::build(scene, base_dir).unwrap());
    (plain, app, root)
}

/// Steps both drivers `frames` times.
fn step_both(plain: &mut Solver, app: &mut App, frames: usize) {
    for _ in 0..frames {
        plain.step();
        app.update();
    }
}

/// Every vertex of every muscle has the same bits in both drivers.
fn assert_same_bits(plain: &Solver, app: &App, root: Entity) {
    let muscles = spawned(app, root).muscles;
    assert_eq!(muscles.len(), plain.muscles().len());
    for (m, &e) in plain.muscles().iter().zip(&muscles) {
        let ecs = positions(app, e);
        let same = m.x.len() == ecs.len()
            && m.x
                .iter()
                .zip(&ecs)
                .all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits));
        assert!(
            same,
            "muscle '{}' differs after {} frames",
            m.name,
            plain.frame()
        );
    }
}

fn p3() -> (Scene, PathBuf) {
    let path = asset("scenes/p3.ron");
    let base = path.parent().unwrap().to_path_buf();
    (Scene::load(&path).unwrap(), base)
}

#[test]
fn bevy_and_plain_drivers_agree_bit_for_bit_on_p3() {
    let (scene, base) = p3();
    let (mut plain, mut app, root) = both_drivers(scene, &base);
    step_both(&mut plain, &mut app, 300);
    assert_same_bits(&plain, &app, root);
    assert_eq!(app.world().resource::<SinewClock>().frame, 300);
}

/// A muscle the other slides on that sits out the last iterations (its
/// own iteration count below the scene's): the plain driver publishes it
/// from buffers each muscle stages in its own task, the plug-in in a pass
/// every iteration; the snapshot the other muscle reads is the same.
#[test]
fn a_muscle_sitting_out_iterations_is_published_alike_by_both_drivers() {
    let (mut scene, base) = p3();
    assert!(scene.settings.iterations > 2);
    scene.muscles[1].params.iterations = Some(2);
    let (mut plain, mut app, root) = both_drivers(scene, &base);
    step_both(&mut plain, &mut app, 120);
    assert_same_bits(&plain, &app, root);
}

/// Iterations in blocks of three ([`SinewSettings::snapshot_interval`]),
/// the brachialis sitting out after two (its block ends early): the
/// plain driver swaps in what each muscle staged at its block's end, the
/// plug-in runs its iteration schedule once per block and publishes in a
/// pass; on two threads the app sweeps colour by colour across muscles
/// for each iteration of a block, the plain solver runs each muscle's
/// block in one task. The same bits.
#[test]
fn blocks_of_iterations_give_the_same_bits_in_both_drivers() {
    for (method, schedule) in [
        (Method::Sequential, SweepSchedule::Auto),
        (Method::ColoredGlobal, SweepSchedule::ByColor),
    ] {
        let (mut scene, base) = p3();
        assert!(scene.settings.iterations > 3);
        scene.settings.snapshot_interval = 3;
        scene.settings.method = method.into();
        scene.settings.threads = 1;
        scene.muscles[1].params.iterations = Some(2);
        let (mut plain, mut app, root) = both_drivers(scene, &base);
        step_both(&mut plain, &mut app, 1);
        let mut settings = app.world_mut().resource_mut::<SinewSettings>();
        assert_eq!(settings.snapshot_interval, 3);
        settings.threads = 2;
        settings.parallel_threshold = 0;
        settings.schedule = schedule;
        step_both(&mut plain, &mut app, 99);
        assert_same_bits(&plain, &app, root);
    }
}

#[test]
fn muscles_in_parallel_give_the_same_bits() {
    let (scene, base) = p3();
    let (mut plain, mut app, root) = both_drivers(scene, &base);
    step_both(&mut plain, &mut app, 1);
    // Muscles and their chunks on the plug-in's pool of 4 (P3 is below the
    // default threshold, so it is lowered), the plain driver on one thread.
    let mut settings = app.world_mut().resource_mut::<SinewSettings>();
    settings.threads = 4;
    settings.parallel_threshold = 0;
    step_both(&mut plain, &mut app, 99);
    assert_same_bits(&plain, &app, root);
}

#[test]
fn global_sweeps_give_the_bits_of_muscle_by_muscle_runs() {
    // The app on 2 threads sweeps colour c of every muscle together; the
    // plain solver on one thread runs each muscle's colours in turn.
    for method in [
        Method::ColoredGlobal,
        Method::Hybrid {
            min_group: 32,
            omega: 1.5,
        },
    ] {
        let (mut scene, base) = p3();
        scene.settings.method = method.into();
        scene.settings.threads = 1;
        let (mut plain, mut app, root) = both_drivers(scene, &base);
        step_both(&mut plain, &mut app, 1);
        let mut settings = app.world_mut().resource_mut::<SinewSettings>();
        settings.threads = 2;
        settings.parallel_threshold = 0;
        settings.schedule = SweepSchedule::ByColor;
        let mut swept = 0;
        for _ in 0..59 {
            step_both(&mut plain, &mut app, 1);
            swept += app.world().resource::<SinewTimings>().step.sweeps_by_color;
        }
        assert_eq!(
            swept,
            59 * 5,
            "{method:?}: every iteration sweeps by colour"
        );
        assert_eq!(plain.timings().sweeps_by_color, 0);
        assert_same_bits(&plain, &app, root);
    }
}

#[test]
fn bevy_and_plain_drivers_agree_with_an_animated_bone() {
    let scene = common::p2_with_moving_ground();
    let (mut plain, mut app, root) = both_drivers(scene, Path::new("."));
    step_both(&mut plain, &mut app, 90);
    assert_same_bits(&plain, &app, root);
}

/// Extent of `points` along `axis`.
fn extent(points: &[CoreVec3], axis: CoreVec3) -> f32 {
    let d = points.iter().map(|p| p.dot(axis));
    d.clone().fold(f32::MIN, f32::max) - d.fold(f32::MAX, f32::min)
}

#[test]
fn activation_through_the_component_shortens_the_muscle() {
    let mut app = app();
    let root = spawn_scene(&mut app, builtin_scene("T1"));
    app.update();
    let muscle = spawned(&app, root).muscles[0];
    let axis = CoreVec3::X;
    let rest = extent(&positions(&app, muscle), axis);
    {
        let mut m = app.world_mut().get_mut::<Muscle>(muscle).unwrap();
        m.driven = false;
        m.activation = 1.0;
    }
    for _ in 0..90 {
        app.update();
    }
    let active = extent(&positions(&app, muscle), axis);
    assert!(
        active < 0.9 * rest,
        "length along the fibres {active} vs rest {rest}"
    );
    let state = app.world().get::<MuscleState>(muscle).unwrap();
    assert_eq!(state.muscle.params.activation, 1.0);
}

/// Moves the bone called "hook" to x = 0.1 from frame 10 on.
fn move_hook(clock: Res<SinewClock>, mut bones: Query<(&SinewBone, &mut Transform)>) {
    if clock.frame >= 10 {
        for (bone, mut t) in &mut bones {
            if bone.name == "hook" {
                t.translation.x = 0.1;
            }
        }
    }
}

#[test]
fn a_bone_moved_by_a_system_drags_its_muscle_the_same_frame() {
    let mut app = app();
    app.add_systems(Update, move_hook);
    let bone = app.world_mut().spawn(SinewBone::new("hook")).id();
    let muscle = app.world_mut().spawn(common::oval_on(bone)).id();
    // The build runs on the async pool: wait for it without stepping far.
    common::update_until(&mut app, |app| {
        app.world().get::<MuscleState>(muscle).is_some()
    });
    let start = positions(&app, muscle)[0];
    while app.world().resource::<SinewClock>().frame < 10 {
        app.update();
    }
    assert!(positions(&app, muscle)[0].distance(start) < 1e-6);
    // Frame 10: the system moves the bone in Update; the attached vertex
    // follows in the same app update.
    app.update();
    let moved = positions(&app, muscle)[0];
    assert!(
        (moved.x - (start.x + 0.1)).abs() < 1e-5,
        "attached vertex at {moved} after the bone moved 0.1 from {start}"
    );
}

#[test]
fn switching_method_at_runtime_keeps_the_simulation_finite_and_continuous() {
    let mut app = app();
    let root = spawn_scene(&mut app, builtin_scene("P1"));
    let mut last: Option<Vec<CoreVec3>> = None;
    let mut worst_step = 0.0f32;
    for method in [
        Method::Sequential,
        Method::Jacobi { omega: 1.5 },
        Method::Colored,
        Method::ColoredGlobal,
        Method::Hybrid {
            min_group: 32,
            omega: 1.5,
        },
        Method::Sequential,
    ] {
        app.world_mut().resource_mut::<SinewSettings>().method = method;
        for _ in 0..40 {
            app.update();
            let now: Vec<CoreVec3> = spawned(&app, root)
                .muscles
                .iter()
                .flat_map(|&e| positions(&app, e))
                .collect();
            assert!(now.iter().all(|p| p.is_finite()), "{method:?}: not finite");
            if let Some(last) = &last {
                let step = now
                    .iter()
                    .zip(last)
                    .map(|(a, b)| a.distance(*b))
                    .fold(0.0, f32::max);
                worst_step = worst_step.max(step);
            }
            last = Some(now);
        }
    }
    // Under one method P1 moves ≤ 0.5 mm a frame; switching (which builds
    // the colour groups or the Jacobi incidence on the spot) stays smooth.
    assert!(worst_step < 0.005, "largest per-frame move {worst_step} m");
}

/// What `muscle` slides on: its connections' targets, in order.
fn targets_of(app: &App, muscle: Entity) -> Vec<Entity> {
    let world = app.world();
    world.get::<Connections>(muscle).map_or_else(Vec::new, |c| {
        c.iter()
            .map(|c| world.get::<ConnectsTo>(c).unwrap().0)
            .collect()
    })
}

#[test]
fn despawning_a_muscle_mid_simulation_unlinks_it() {
    let path = asset("scenes/p3.ron");
    let mut app = app();
    let root = spawn_scene(&mut app, SinewScene::load(&path).unwrap());
    for _ in 0..30 {
        app.update();
    }
    let muscles = spawned(&app, root).muscles;
    let (gone, kept) = (muscles[1], muscles[0]);
    assert!(
        targets_of(&app, kept).contains(&gone),
        "P3's first muscle targets the second"
    );
    app.world_mut().entity_mut(gone).despawn();
    for _ in 0..30 {
        app.update();
    }
    // The connection to the despawned muscle went with it.
    assert!(!targets_of(&app, kept).contains(&gone));
    assert!(
        !targets_of(&app, kept).is_empty(),
        "the ground is still there"
    );
    assert!(positions(&app, kept).iter().all(|p| p.is_finite()));
    assert_eq!(app.world().resource::<SinewClock>().frame, 60);
}

#[test]
fn invalid_settings_and_parameters_are_refused_without_harm() {
    let mut app = app();
    let root = spawn_scene(&mut app, builtin_scene("P1"));
    app.update();
    let muscle = spawned(&app, root).muscles[0];
    app.world_mut().resource_mut::<SinewSettings>().dt = f32::NAN;
    app.world_mut()
        .get_mut::<Muscle>(muscle)
        .unwrap()
        .compliance
        .fiber = -1.0;
    for _ in 0..10 {
        app.update();
    }
    let state = app.world().get::<MuscleState>(muscle).unwrap();
    assert!(state.muscle.params.compliance.fiber >= 0.0);
    assert!(positions(&app, muscle).iter().all(|p| p.is_finite()));
    assert_eq!(app.world().resource::<SinewClock>().frame, 11);
}

#[test]
fn a_failed_build_is_reported_on_the_entity() {
    let mut app = app();
    let e = app
        .world_mut()
        .spawn(MuscleBuilder::new(
            "missing",
            MuscleSource::File("no/such/file.obj".into(), Default::default()),
        ))
        .id();
    common::update_until(&mut app, |app| app.world().get::<BuildFailed>(e).is_some());
    let failed = app.world().get::<BuildFailed>(e).expect("reported");
    assert!(
        matches!(*failed.0, MuscleBuildError::Mesh(_)),
        "{}",
        failed.0
    );
    assert!(failed.0.to_string().contains("file.obj"), "{}", failed.0);
    assert!(app.world().get::<MuscleState>(e).is_none());
}

/// One scene spawned twice (two characters from one asset): each spawn's
/// bone reads the same bone geometry — a clone of the scene's target, not
/// a copy — and the two step as one another, bit for bit, each on its own
/// bones.
#[test]
fn a_scene_spawned_twice_shares_its_bones_geometry() {
    let path = asset("scenes/t3.ron");
    let scene = Arc::new(SinewScene::load(&path).unwrap());
    let mut app = app();
    let roots: Vec<Entity> = (0..2)
        .map(|_| {
            (app.world_mut())
                .spawn(SinewSceneRoot::Built(scene.clone()))
                .id()
        })
        .collect();
    app.update();
    let [first, second] = [0, 1].map(|k| spawned(&app, roots[k]));
    let target = |bone: Entity| app.world().get::<BoneTarget>(bone).map(|t| &t.0);
    let mut shared = 0;
    for (&a, &b) in first.bones.iter().zip(&second.bones) {
        assert_ne!(a, b);
        if let (Some(ta), Some(tb)) = (target(a), target(b)) {
            assert!(ta.shares_geometry_with(tb), "{}", ta.name);
            shared += 1;
        }
    }
    assert!(shared >= 3, "{shared} bones with a mesh");
    for _ in 0..5 {
        app.update();
    }
    for (&a, &b) in first.muscles.iter().zip(&second.muscles) {
        assert!(positions(&app, a) == positions(&app, b), "muscle {a}");
    }
}
