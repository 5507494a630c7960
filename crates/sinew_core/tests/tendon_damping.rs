//! The tendon mask and the damping map: tendon neither shortens nor bulges
//! with activation while the belly does; a damping multiplier scales the
//! damping rate per vertex; bad values and lengths are refused.

use sinew_core::glam::Vec3;
use sinew_core::muscle::longest_axis;
use sinew_core::scene::{Scene, builtin};
use std::path::Path;

/// T1 (the oval contracting to a = 1 at frame 40) with `tendon` masking the
/// vertices farther than `from` (fraction of the half-length) from its centre
/// along its fibres; the surface at frame 60, and the mask used.
fn t1_with_tendon_ends(from: Option<f32>) -> (Vec<Vec3>, Vec<Vec3>, Vec<f32>) {
    let mut scene = builtin("T1").unwrap();
    let mut solver = scene.instantiate(Path::new(".")).unwrap();
    let rest = solver.muscles()[0].rest[..solver.muscles()[0].surface_count].to_vec();
    let axis = longest_axis(&rest);
    let centre = rest.iter().sum::<Vec3>() / rest.len() as f32;
    let half = rest
        .iter()
        .map(|p| (*p - centre).dot(axis).abs())
        .fold(0.0, f32::max);
    let mask: Vec<f32> = rest
        .iter()
        .map(|p| match from {
            Some(f) if (*p - centre).dot(axis).abs() > f * half => 1.0,
            _ => 0.0,
        })
        .collect();
    if from.is_some() {
        scene.muscles[0].maps.tendon = Some(mask.clone());
        solver = scene.instantiate(Path::new(".")).unwrap();
    }
    for _ in 0..60 {
        solver.step();
    }
    (rest, solver.muscles()[0].surface_positions().to_vec(), mask)
}

/// Length along `axis` of the points whose mask is `tendon`.
fn extent_of(points: &[Vec3], mask: &[f32], tendon: bool, axis: Vec3) -> f32 {
    let d: Vec<f32> = points
        .iter()
        .zip(mask)
        .filter(|(_, m)| (**m == 1.0) == tendon)
        .map(|(p, _)| p.dot(axis))
        .collect();
    d.iter().copied().fold(f32::MIN, f32::max) - d.iter().copied().fold(f32::MAX, f32::min)
}

#[test]
fn tendon_ends_keep_their_rest_lengths_while_the_belly_contracts() {
    let (rest, plain, _) = t1_with_tendon_ends(None);
    let (_, masked, mask) = t1_with_tendon_ends(Some(0.5));
    let axis = longest_axis(&rest);
    let tendons = mask.iter().filter(|m| **m == 1.0).count();
    assert!(
        tendons > 10 && tendons < rest.len() - 10,
        "{tendons} tendon vertices"
    );
    let whole = |p: &[Vec3]| extent_of(p, &vec![0.0; p.len()], false, axis);
    let (rest_len, plain_len, masked_len) = (whole(&rest), whole(&plain), whole(&masked));
    println!(
        "T1 at a = 1: length {:.3} × rest without a tendon, {:.3} × rest with tendon ends",
        plain_len / rest_len,
        masked_len / rest_len
    );
    // Half the length is tendon: the whole shortens about half as much.
    assert!(plain_len / rest_len < 0.8, "the plain oval contracts");
    assert!(
        masked_len / rest_len > 1.0 - 0.7 * (1.0 - plain_len / rest_len),
        "with tendon ends it contracts less: {masked_len} vs {plain_len} (rest {rest_len})"
    );
    // The rest lengths themselves: a fibre between two tendon vertices keeps
    // its length; one in the belly shortens as without a mask.
    let mut scene = builtin("T1").unwrap();
    scene.muscles[0].maps.tendon = Some(mask.clone());
    let mut with = scene.instantiate(Path::new(".")).unwrap();
    let mut without = builtin("T1").unwrap().instantiate(Path::new(".")).unwrap();
    for solver in [&mut with, &mut without] {
        solver.set_activation(0, 1.0);
        solver.step();
    }
    let (mw, mo) = (&with.muscles()[0], &without.muscles()[0]);
    let fiber = &mw.constraints.fiber;
    let (mut tendon_edges, mut belly_edges) = (0, 0);
    for i in 0..fiber.a.len() {
        let (a, b) = (fiber.a[i].index(), fiber.b[i].index());
        let initial = mw.rest[a].distance(mw.rest[b]);
        match (mask[a], mask[b]) {
            (1.0, 1.0) => {
                tendon_edges += 1;
                assert!((fiber.rest[i] - initial).abs() < 1e-7, "tendon edge {i}");
            }
            (0.0, 0.0) => {
                belly_edges += 1;
                assert_eq!(
                    fiber.rest[i], mo.constraints.fiber.rest[i],
                    "belly edge {i}"
                );
            }
            _ => {}
        }
    }
    assert!(tendon_edges > 0 && belly_edges > 0);
}

/// P1's oval without an internal structure, falling freely for 0.5 s with
/// damping rate `c` and a damping map of `scale` on every vertex: its fall.
fn fall(c: f32, scale: Option<f32>) -> f32 {
    let mut scene: Scene = builtin("P1").unwrap();
    scene.bones.clear();
    let m = &mut scene.muscles[0];
    m.targets.clear();
    m.attachments.clear();
    m.params.damping = c;
    m.params.internal.enabled = false;
    let mut solver = scene.instantiate(Path::new(".")).unwrap();
    if let Some(s) = scale {
        let n = solver.muscles()[0].surface_count;
        scene.muscles[0].maps.damping = Some(vec![s; n]);
        solver = scene.instantiate(Path::new(".")).unwrap();
    }
    let mean_y = |s: &sinew_core::Solver| {
        let p = s.muscles()[0].surface_positions();
        p.iter().map(|p| p.y).sum::<f32>() / p.len() as f32
    };
    let start = mean_y(&solver);
    for _ in 0..30 {
        solver.step();
    }
    start - mean_y(&solver)
}

#[test]
fn a_damping_map_scales_the_damping_rate_per_vertex() {
    let (twice, doubled_by_map) = (fall(3.08, None), fall(1.54, Some(2.0)));
    let (free, undamped_by_map) = (fall(0.0, None), fall(3.08, Some(0.0)));
    println!(
        "fall in 0.5 s: c = 3.08 {:.2} mm, c = 1.54 × map 2 {:.2} mm; free {:.2} mm, c = 3.08 × map 0 {:.2} mm",
        twice * 1e3,
        doubled_by_map * 1e3,
        free * 1e3,
        undamped_by_map * 1e3
    );
    assert!(
        (twice - doubled_by_map).abs() < 1e-6,
        "{twice} vs {doubled_by_map}"
    );
    assert!(
        (free - undamped_by_map).abs() < 1e-6,
        "{free} vs {undamped_by_map}"
    );
    assert!(free > twice * 1.2, "damping slows the fall");
}

#[test]
fn bad_tendon_and_damping_maps_are_refused() {
    let n = builtin("P1")
        .unwrap()
        .instantiate(Path::new("."))
        .unwrap()
        .muscles()[0]
        .surface_count;
    let build = |tendon: Option<Vec<f32>>, damping: Option<Vec<f32>>| {
        let mut scene = builtin("P1").unwrap();
        scene.muscles[0].maps.tendon = tendon;
        scene.muscles[0].maps.damping = damping;
        scene
            .instantiate(Path::new("."))
            .err()
            .map(|e| e.to_string())
    };
    let mut over = vec![0.0; n];
    over[7] = 1.5;
    let error = build(Some(over), None).expect("a mask of 1.5 is refused");
    assert!(
        error.contains("tendon") && error.contains("vertex 7"),
        "{error}"
    );
    let mut negative = vec![1.0; n];
    negative[3] = -1.0;
    let error = build(None, Some(negative)).expect("a negative multiplier is refused");
    assert!(
        error.contains("damping") && error.contains("vertex 3"),
        "{error}"
    );
    let error = build(Some(vec![0.0; n - 1]), None).expect("a short map is refused");
    assert!(error.contains("tendon"), "{error}");
    assert!(build(Some(vec![0.5; n]), Some(vec![2.0; n])).is_none());
}
