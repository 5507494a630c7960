use super::*;
use crate::mesh::primitives::MeshGenerator;

fn ellipsoid_target() -> TargetSurface {
    let mesh = MeshGenerator::Ellipsoid {
        center: Vec3::ZERO,
        radii: Vec3::new(0.05, 0.02, 0.025),
        segments: 16,
        stacks: 12,
    }
    .build("target")
    .unwrap();
    TargetSurface::new(
        "target",
        TargetSource::Muscle(0),
        mesh.positions,
        mesh.triangles,
    )
}

/// Deterministic pseudo-random unit-ish vectors.
fn jitter(i: usize) -> Vec3 {
    let k = i as f32;
    Vec3::new((k * 12.9898).sin(), (k * 78.233).sin(), (k * 37.719).sin())
}

fn brute_force(t: &TargetSurface, q: Vec3) -> f32 {
    (0..t.triangles().len() as u32)
        .map(|i| t.closest_on_triangle(i, q).0.distance(q))
        .fold(f32::MAX, f32::min)
}

#[test]
fn walk_reaches_the_closest_point_of_a_convex_target() {
    let t = ellipsoid_target();
    for i in 0..200 {
        // A query 2–20 mm outside the surface, started from the triangle
        // closest to a point a little way around the surface.
        let dir = jitter(i + 1).normalize();
        let on_surface = t.closest(dir * 0.06, None).unwrap();
        let q = Vec3::from(
            on_surface.point + on_surface.normal * (0.002 + 0.018 * (i % 10) as f32 / 9.0),
        );
        let start = t
            .closest(q + 0.01 * jitter(i + 1000), None)
            .unwrap()
            .triangle;
        let walked = t.walk(q, start).expect("walk converges");
        let exact = brute_force(&t, q);
        assert!(
            (walked.distance - exact).abs() <= 1e-6 + 1e-4 * exact,
            "query {i}: walk {} vs exact {exact}",
            walked.distance
        );
    }
}

#[test]
fn full_search_stays_exact_on_a_moved_target_before_refit() {
    let mut t = ellipsoid_target();
    let moved: Vec<Vec3> = t
        .positions()
        .iter()
        .enumerate()
        .map(|(i, p)| *p * 1.05 + 0.002 * jitter(i) + Vec3::new(0.003, 0.0, 0.0))
        .collect();
    t.publish(&moved);
    assert!(t.slack > 0.0);
    for i in 0..200 {
        let q = 0.07 * jitter(i + 7);
        let hit = t.closest(q, None).unwrap();
        let exact = brute_force(&t, q);
        assert!(
            (hit.distance - exact).abs() <= 1e-6,
            "query {i}: BVH {} vs exact {exact}",
            hit.distance
        );
    }
    t.refit(true);
    assert_eq!(t.slack, 0.0);
}

#[test]
fn a_staged_publish_gives_the_snapshot_and_slack_of_a_copying_one() {
    let moved: Vec<Vec3> = ellipsoid_target()
        .positions()
        .iter()
        .enumerate()
        .map(|(i, p)| *p * 1.02 + 0.001 * jitter(i))
        .collect();
    let mut copied = ellipsoid_target();
    copied.publish(&moved);
    let mut swapped = ellipsoid_target();
    let mut staged = moved.clone();
    let slack = swapped.moved_squared(&staged);
    swapped.publish_staged(&mut staged, slack);
    assert_eq!(swapped.positions(), copied.positions());
    assert_eq!(swapped.slack.to_bits(), copied.slack.to_bits());
    assert!(swapped.slack > 0.0);
    // A staged surface that is not finite is not published: the muscles
    // sliding on it keep its last finite one.
    let mut bad = moved.clone();
    bad[3].x = f32::NAN;
    let bad_slack = swapped.moved_squared(&bad);
    swapped.publish_staged(&mut bad, bad_slack);
    assert_eq!(swapped.positions(), moved);
    assert!(bad[3].x.is_nan(), "the buffer keeps what was staged");
}

/// The largest move, kept in four lanes, is the one-lane pass's maximum to
/// the bit for any length (a remainder in any lane), and NaN or infinite
/// wherever a position that is not finite lies.
#[test]
fn the_largest_move_is_the_one_lane_maximum() {
    let t = ellipsoid_target();
    let fitted = t.positions().to_vec();
    let one_lane = |positions: &[Vec3]| {
        (positions.iter().zip(&fitted))
            .map(|(p, f)| p.distance_squared(*f))
            .fold(0.0f32, |m, d| if d > m || d.is_nan() { d } else { m })
    };
    for n in [0, 1, 2, 3, 4, 5, 7, 8, 13, fitted.len()] {
        let moved: Vec<Vec3> = (fitted[..n].iter().enumerate())
            .map(|(i, p)| *p + 0.001 * jitter(i + 7 * n))
            .collect();
        assert_eq!(
            t.moved_squared(&moved).to_bits(),
            one_lane(&moved).to_bits(),
            "{n}"
        );
        for k in 0..n {
            let mut bad = moved.clone();
            bad[k].y = f32::NAN;
            assert!(t.moved_squared(&bad).is_nan(), "{n}: NaN at {k}");
            bad[k].y = f32::INFINITY;
            assert_eq!(t.moved_squared(&bad), f32::INFINITY, "{n}: infinite at {k}");
        }
    }
}

/// A posed target's hit normal (normalised once, after the transform) is
/// the unit interpolated normal carried by the pose: for a rotation with a
/// uniform scale, within a few ulps of normalising before the transform
/// too, and of unit length.
#[test]
fn a_posed_hit_has_the_unit_interpolated_normal() {
    let mut t = ellipsoid_target();
    let rotation = glam::Quat::from_axis_angle(Vec3::new(0.3, -0.8, 0.5).normalize(), 1.1);
    let pose = Affine3A::from_scale_rotation_translation(
        Vec3::splat(1.7),
        rotation,
        Vec3::new(0.2, -0.1, 0.4),
    );
    t.set_transform(pose);
    for i in 0..200 {
        let q = pose.transform_point3(jitter(i + 7) * 0.05);
        let hit = t.closest_within(q, None, f32::MAX).unwrap();
        let [a, b, c] = t.triangles()[hit.triangle as usize];
        let n = t.normals();
        let bary = hit.barycentric;
        let local = n[a as usize] * bary.x + n[b as usize] * bary.y + n[c as usize] * bary.z;
        let twice = pose.transform_vector3(local.normalize()).normalize();
        let normal = Vec3::from(hit.normal);
        assert!(
            (normal.length() - 1.0).abs() < 1e-6,
            "query {i}: |n| {}",
            normal.length()
        );
        assert!(
            normal.distance(twice) < 1e-6,
            "query {i}: {normal} vs {twice}"
        );
    }
}

/// A bone's full search (its leaves' triangles four at a time in SIMD
/// lanes) finds what the scalar search over the same mesh finds, to the
/// bit: the same triangle, point, barycentric coordinates and distance, near
/// the surface and far from it, inside and out, from a warm triangle and
/// without, bounded and not. The mesh has a sliver and a point triangle (a
/// lane's degenerate divisions). Seen to fail with the lanes' dot products
/// summed as `x + (y + z)`, and the interior's point as `a + (ab·v + ac·w)`.
#[test]
fn a_bones_packed_search_finds_the_scalar_searchs_hit() {
    let mesh = test_ellipsoid();
    let mut triangles = mesh.triangles;
    // A point triangle and a sliver along an existing edge.
    let [a, b, _] = triangles[7];
    triangles.extend([[a, a, a], [a, b, a]]);
    let bone = TargetSurface::new(
        "bone",
        TargetSource::Bone(0),
        mesh.positions.clone(),
        triangles.clone(),
    );
    let scalar = TargetSurface::new("scalar", TargetSource::Muscle(0), mesh.positions, triangles);
    assert!(!bone.geometry.leaf_packs.is_empty() && scalar.geometry.leaf_packs.is_empty());
    let bits = |h: Option<ClosestHit>| {
        h.map(|h| {
            let v = |v: Vec3A| v.to_array().map(f32::to_bits);
            (
                h.triangle,
                v(h.point),
                v(h.barycentric),
                h.distance.to_bits(),
            )
        })
    };
    let mut found = 0;
    for i in 0..2000 {
        let q = (0.03 + 0.04 * (i % 7) as f32 / 6.0) * jitter(i + 11);
        let warm = (i % 3 == 0).then_some((i * 37 % bone.triangles().len()) as u32);
        let bound = if i % 5 == 0 { 0.004 } else { f32::MAX };
        let (packed, plain) = (
            bone.closest_within(q, warm, bound),
            scalar.closest_within(q, warm, bound),
        );
        found += usize::from(packed.is_some());
        assert_eq!(bits(packed), bits(plain), "query {i} at {q}");
    }
    assert!(found > 1500, "{found}");
}
