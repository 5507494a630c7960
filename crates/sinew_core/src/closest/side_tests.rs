//! Tests of which side of a rigid target a point is on ([`super::side`]).

use super::{SideMemo, TargetSource, TargetSurface};
use glam::Vec3;

/// A closed blade: a tetrahedron with a sharp edge along z (from the
/// origin, 10 mm long) whose two sides are unequal, 3 mm and 40 mm wide,
/// meeting at a few degrees: the edge's vertex normals follow the wide
/// side, so beside the narrow one near the edge they point the other way,
/// as on the thin edge of a rib.
fn blade() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let positions = [
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 10.0],
        [3.0, 0.4, 5.0],
        [40.0, -1.0, 5.0],
    ]
    .map(|p| Vec3::from(p) * 1e-3)
    .to_vec();
    let mut triangles = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    // Outward winding: positive volume.
    if crate::mesh::signed_volume(&triangles, &positions) < 0.0 {
        for t in &mut triangles {
            t.swap(1, 2);
        }
    }
    (positions, triangles)
}

/// A closed L-shaped bracket, two plates 1.5 mm thick and 30 mm long joined
/// at a right angle, 10 mm deep.
fn bracket() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let outline = [
        (0.0, 0.0),
        (30.0, 0.0),
        (30.0, 1.5),
        (1.5, 1.5),
        (1.5, 30.0),
        (0.0, 30.0),
    ];
    let mut positions = Vec::new();
    for z in [0.0, 10.0] {
        for &(x, y) in &outline {
            positions.push(Vec3::new(x, y, z) * 1e-3);
        }
    }
    let cap = [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]];
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    for [a, b, c] in cap {
        triangles.push([a, c, b]);
        triangles.push([a + 6, b + 6, c + 6]);
    }
    for i in 0..6u32 {
        let j = (i + 1) % 6;
        triangles.push([i, j, j + 6]);
        triangles.push([i, j + 6, i + 6]);
    }
    (positions, triangles)
}

/// The bracket with a loose sheet floating in its corner, and either one
/// wall wound inward (`hole: false`) or one side triangle gone (`true`).
fn damaged_bracket(hole: bool) -> TargetSurface {
    let (mut positions, mut triangles) = bracket();
    if hole {
        triangles.remove(9);
    } else {
        triangles[12].swap(1, 2);
    }
    let base = positions.len() as u32;
    for p in [[20.0, 10.0, 5.0], [25.0, 10.0, 5.0], [20.0, 15.0, 5.0]] {
        positions.push(Vec3::from(p) * 1e-3);
    }
    triangles.push([base, base + 1, base + 2]);
    bone(positions, triangles)
}

/// Where a point really is: inside the undamaged bracket, by its winding
/// number where it is decisive (`None` near the hole, where it is not).
fn truth(q: Vec3) -> Option<bool> {
    let (positions, triangles) = bracket();
    let whole = bone(positions, triangles);
    let w = whole.winding_number(q);
    ((w - 0.5).abs() > 0.3).then_some(w > 0.5)
}

/// Whether a point has a side a test can judge: the undamaged bracket's
/// winding number is decisive there, and beside the hole of `t` (a
/// [`damaged_bracket`] with `hole`) the damaged surface's own is too (it is
/// about ½ there: no side is right).
fn has_a_side(t: &TargetSurface, hole: bool, q: Vec3) -> bool {
    truth(q).is_some() && (!hole || (t.winding_number(q) - 0.5).abs() > 0.3)
}

/// Query points on a grid around the bracket, 0.3–6 mm from it.
fn bracket_queries(t: &TargetSurface) -> Vec<Vec3> {
    let mut out = Vec::new();
    for i in 0..24 {
        for j in 0..24 {
            for k in 0..5 {
                let q = Vec3::new(
                    i as f32 * 1.4 - 1.0,
                    j as f32 * 1.4 - 1.0,
                    k as f32 * 2.9 - 0.8,
                );
                let q = q * 1e-3;
                let d = t.closest(q, None).unwrap().distance;
                if (0.3e-3..6e-3).contains(&d) {
                    out.push(q);
                }
            }
        }
    }
    out
}

fn bone(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> TargetSurface {
    TargetSurface::new("bone", TargetSource::Bone(0), positions, triangles)
}

/// Query points on a grid around the blade's narrow side and edge, 0.2–4
/// mm from it.
fn queries(t: &TargetSurface) -> Vec<Vec3> {
    let mut out = Vec::new();
    for i in 0..30 {
        for j in 0..30 {
            for k in 0..5 {
                let q = Vec3::new(
                    i as f32 * 0.2 - 2.0,
                    j as f32 * 0.2 - 2.0,
                    k as f32 * 2.0 + 1.0,
                );
                let q = q * 1e-3;
                let d = t.closest(q, None).unwrap().distance;
                if (0.2e-3..4e-3).contains(&d) {
                    out.push(q);
                }
            }
        }
    }
    out
}

/// Points of `queries` whose exact closest point's side disagrees with
/// `truth`, settled by [`TargetSurface::settle_side`] or not.
fn wrong_sides(
    t: &TargetSurface,
    queries: &[Vec3],
    truth: impl Fn(Vec3) -> bool,
    settle: bool,
) -> usize {
    queries
        .iter()
        .filter(|&&q| {
            let hit = t.closest(q, None).unwrap();
            let hit = if settle {
                t.settle_side(q, hit, &mut SideMemo::default(), 0)
            } else {
                hit
            };
            hit.is_inside() != truth(q)
        })
        .count()
}

#[test]
fn a_sharp_edge_reads_every_side_right_from_its_pseudo_normals() {
    let (positions, triangles) = blade();
    let t = bone(positions, triangles);
    let queries = queries(&t);
    assert!(queries.len() > 300, "{}", queries.len());
    // The interpolated vertex normals misread some: the case is real.
    let truth = |q| t.contains(q);
    assert!(wrong_sides(&t, &queries, truth, false) > 0);
    assert_eq!(wrong_sides(&t, &queries, truth, true), 0);
}

#[test]
fn a_flipped_wall_a_loose_sheet_and_a_hole_are_read_by_the_winding_number() {
    for hole in [false, true] {
        let t = damaged_bracket(hole);
        let queries: Vec<Vec3> = bracket_queries(&t)
            .into_iter()
            .filter(|&q| has_a_side(&t, hole, q))
            .collect();
        assert!(queries.len() > 300, "{}", queries.len());
        let truth = |q| truth(q).unwrap();
        assert!(wrong_sides(&t, &queries, truth, false) > 0, "hole {hole}");
        assert_eq!(wrong_sides(&t, &queries, truth, true), 0, "hole {hole}");
    }
}

#[test]
fn a_remembered_side_holds_within_the_distance_it_was_taken_at() {
    let t = damaged_bracket(false);
    let mut memo = SideMemo::default();
    let mut taken = 0;
    for q in bracket_queries(&t) {
        let Some(inside) = truth(q) else { continue };
        let hit = t.closest(q, None).unwrap();
        let before = memo;
        let settled = t.settle_side(q, hit, &mut memo, 0);
        taken += usize::from(memo != before);
        assert_eq!(settled.is_inside(), inside, "{q}");
    }
    assert!(taken > 0);
}

/// A vertex moving around a damaged bone in steps of a few millimetres
/// asks for a winding number only where no decision is within reach (a
/// third of the steps out of every ball are read by reaching one), and
/// every side read is the one a winding number there gives, and the right
/// one.
#[test]
fn a_side_reached_from_a_decision_is_the_winding_numbers() {
    for hole in [false, true] {
        let t = damaged_bracket(hole);
        // From each query of the grid, a drift of 2 mm in steps of 0.5 mm.
        let path: Vec<Vec3> = bracket_queries(&t)
            .into_iter()
            .flat_map(|q| (0..5).map(move |s| q + Vec3::new(0.3, 0.4, 0.0) * (s as f32 * 1e-3)))
            .filter(|&q| t.closest(q, None).unwrap().distance > 0.3e-3)
            .filter(|&q| has_a_side(&t, hole, q))
            .collect();
        let mut memo = SideMemo::default();
        let (mut decided, mut reached) = (0, 0);
        for q in path {
            let hit = t.closest(q, None).unwrap();
            let before = memo.newest();
            let settled = t.settle_side(q, hit, &mut memo, 0);
            let after = memo.newest();
            decided += usize::from(after[0] != before[0]);
            reached += usize::from(after[1] != before[1]);
            let by_winding = t.settle_side(q, hit, &mut SideMemo::default(), 0);
            assert_eq!(settled.is_inside(), by_winding.is_inside(), "{q}");
            assert_eq!(settled.is_inside(), truth(q).unwrap(), "{q}");
        }
        // A third of the steps out of every ball reach one.
        assert!(
            decided > 0 && 3 * reached > reached + decided,
            "hole {hole}: {reached} reached, {decided} decided"
        );
    }
}

/// A vertex near two bones asks about both in turn (its closest data, its
/// bone contacts): the decision about one survives a decision about the
/// other in between, so asking again takes no new winding number.
#[test]
fn a_side_taken_for_one_bone_survives_one_taken_for_another() {
    let t = damaged_bracket(false);
    let (mut decided, mut retaken) = (0, 0);
    for q in bracket_queries(&t) {
        let hit = t.closest(q, None).unwrap();
        let mut memo = SideMemo::default();
        t.settle_side(q, hit, &mut memo, 0);
        if memo == SideMemo::default() {
            continue; // no winding number needed here
        }
        decided += 1;
        t.settle_side(q, hit, &mut memo, 1);
        let before = memo;
        t.settle_side(q, hit, &mut memo, 0);
        retaken += usize::from(memo != before);
    }
    assert!(decided > 0);
    assert_eq!(retaken, 0, "of {decided}");
}

/// A ground plane (two triangles, open) has one exact normal and no
/// inside: a point just below it keeps the plane's normal and its negative
/// signed distance, where a winding number (±½ that close to a sheet) would
/// decide its side by rounding; a bent sheet still carries pseudo-normals.
#[test]
fn a_flat_surface_keeps_its_normal() {
    let positions: Vec<Vec3> = [
        [-1.0, 0.0, -1.0],
        [1.0, 0.0, -1.0],
        [1.0, 0.0, 1.0],
        [-1.0, 0.0, 1.0],
    ]
    .map(Vec3::from)
    .to_vec();
    let triangles = vec![[0, 2, 1], [0, 3, 2]];
    let plane = TargetSurface::new(
        "ground",
        TargetSource::Bone(0),
        positions.clone(),
        triangles.clone(),
    );
    assert!(plane.geometry.pseudo_normals.is_empty());
    let below = Vec3::new(0.3, -0.0015, 0.2);
    let hit = plane.closest(below, None).unwrap();
    let settled = plane.settle_side(below, hit, &mut SideMemo::default(), 0);
    assert_eq!(settled, hit);
    assert!(hit.signed_distance < 0.0 && hit.normal.y > 0.99);
    let mut bent = positions;
    bent[2].y = 0.5;
    let sheet = TargetSurface::new("bent", TargetSource::Bone(0), bent, triangles);
    assert!(!sheet.geometry.pseudo_normals.is_empty());
}
