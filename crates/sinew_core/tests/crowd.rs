//! A crowd: copies of a body side by side in one solver, each on its own
//! bones, later in its animation by its delay.

use sinew_core::Solver;
use sinew_core::glam::Vec3;
use sinew_core::scene::{Scene, builtin};
use std::path::Path;

fn t3() -> (Scene, &'static Path) {
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/scenes/t3.ron"
    ));
    (Scene::load(path).unwrap(), path.parent().unwrap())
}

/// The largest distance of a crowd's copy `k` from the scene moved by
/// `k × spacing`.
fn distance_from_moved(one: &Solver, crowd: &Solver, spacing: Vec3, k: usize) -> f32 {
    let muscles = one.muscles().len();
    let mut worst = 0.0f32;
    for (i, m) in one.muscles().iter().enumerate() {
        let copy = &crowd.muscles()[k * muscles + i];
        assert_eq!(copy.x.len(), m.x.len());
        for (a, b) in m.x.iter().zip(&copy.x) {
            worst = worst.max((*a + spacing * k as f32 - *b).length());
        }
    }
    worst
}

/// Steps `scene` and a crowd of three undelayed copies of it `frames`
/// frames; every copy must be within `tolerance` of the scene moved.
fn copies_follow(scene: &Scene, base: &Path, spacing: Vec3, frames: usize, tolerance: f32) {
    let crowd = scene.crowd(3, spacing, 0.0).unwrap();
    let mut one = scene.instantiate(base).unwrap();
    let mut three = crowd.instantiate(base).unwrap();
    assert_eq!(three.muscles().len(), 3 * one.muscles().len());
    assert_eq!(three.bones().len(), 3 * one.bones().len());
    for _ in 0..frames {
        one.step();
        three.step();
    }
    assert_eq!(distance_from_moved(&one, &three, spacing, 0), 0.0);
    for k in 1..3 {
        let d = distance_from_moved(&one, &three, spacing, k);
        assert!(
            d < tolerance,
            "{}: copy {k} is {d} m from the scene moved",
            scene.name
        );
    }
}

/// Without a delay every copy moves as the scene, moved by its offset, up
/// to f32 rounding (positions a metre further out round differently).
#[test]
fn copies_without_delay_move_as_the_scene_does() {
    // P3: two muscles pressed together, at rest.
    let p3 = builtin("P3").unwrap();
    copies_follow(&p3, Path::new("."), Vec3::new(0.5, 0.0, 0.25), 60, 1e-4);
    // T3, an animated arm with a skeleton and sensors: the first frames,
    // before a contact decided by a rounding amplifies the difference (the
    // arm's motion is sensitive to it: after 40 frames copies differ by
    // 3 mm on average).
    let (t3, base) = t3();
    copies_follow(&t3, base, Vec3::new(0.6, 0.0, 0.0), 3, 1e-5);
}

/// A delayed copy holds its first pose for its delay, then replays the
/// scene's motion that much later.
#[test]
fn a_delayed_copy_replays_the_motion_later() {
    let (scene, base) = t3();
    let spacing = Vec3::new(0.0, 0.0, 0.8);
    let dt = scene.settings.dt;
    let delay = 30.0 * dt;
    let crowd = scene.crowd(2, spacing, delay).unwrap();
    assert!(crowd.frames >= scene.frames + 30);
    let mut solver = crowd.instantiate(base).unwrap();
    let bones = scene.bones.len();
    let mut poses = Vec::new();
    for _ in 0..90 {
        solver.step();
        poses.push(
            solver
                .bones()
                .iter()
                .map(|b| b.transform)
                .collect::<Vec<_>>(),
        );
    }
    let moved = poses[29][..bones]
        .iter()
        .zip(&poses[59][..bones])
        .any(|(a, b)| (a.translation - b.translation).length() > 1e-3);
    assert!(
        moved,
        "the scene's bones do not move between frames 30 and 60"
    );
    for frame in [45usize, 59, 89] {
        // Step f ends at time (f + 1)·dt: the copy is then at the scene's
        // time (f − 29)·dt, which step f − 30 ended at.
        let scene_then = frame - 30;
        for b in 0..bones {
            let copy = poses[frame][bones + b];
            let original = poses[scene_then][b];
            let expected = original.translation + sinew_core::glam::Vec3A::from(spacing);
            let error = (copy.translation - expected).length()
                + (copy.matrix3 - original.matrix3)
                    .abs()
                    .to_cols_array()
                    .iter()
                    .sum::<f32>();
            assert!(
                error < 1e-3,
                "bone {b} of the copy at frame {frame} is {error} from the scene's at {scene_then}"
            );
        }
    }
}

/// Copies touch only themselves: every reference of copy 1 names copy 1.
#[test]
fn copies_refer_only_to_themselves() {
    let (scene, _) = t3();
    let crowd = scene.crowd(2, Vec3::X, 0.5).unwrap();
    let copy: Vec<_> = crowd
        .muscles
        .iter()
        .filter(|m| m.name.ends_with("#1"))
        .collect();
    assert_eq!(copy.len(), scene.muscles.len());
    for m in copy {
        assert!(
            m.targets.iter().all(|t| t.ends_with("#1")),
            "{:?}",
            m.targets
        );
        assert!(
            m.attachments
                .iter()
                .filter_map(|a| a.bone.as_ref())
                .all(|b| b.ends_with("#1"))
        );
    }
    let skeleton = crowd.skeleton.as_ref().unwrap();
    assert_eq!(
        skeleton.bodies.len(),
        2 * scene.skeleton.as_ref().unwrap().bodies.len()
    );
}

#[test]
fn bad_crowds_are_refused_by_name() {
    let (scene, _) = t3();
    for (copies, spacing, delay, words) in [
        (0, Vec3::X, 0.0, "0 copies"),
        (5000, Vec3::X, 0.0, "5000 copies"),
        (2, Vec3::NAN, 0.0, "spacing"),
        (2, Vec3::X, -1.0, "delay"),
        (2, Vec3::X, f32::INFINITY, "delay"),
    ] {
        let error = scene.crowd(copies, spacing, delay).unwrap_err().to_string();
        assert!(error.contains(words) && error.contains("crowd"), "{error}");
    }
}
