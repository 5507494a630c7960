//! Measurements of a running simulation: the figures the anatomy scenes are
//! judged by (finiteness, attachment error, muscle–bone penetration, volume,
//! activation and belly cross-section), whether muscles keep their shape
//! (edge strain, flipped triangles, deviation from rest: [`ShapeReference`])
//! and whether they come to rest (velocity, kinetic energy and acceleration
//! over the last second) and how a simulated skin sits (inside what it
//! slides on, off its skinned position, its bulge over active muscles),
//! collected frame by frame; [`Thresholds`] and
//! [`RunMetrics::verdicts`] judge them.

mod forced;
mod metrics;
mod residual;
mod shape;
mod skin;
mod verdict;

pub use forced::ForcedStrain;
pub use metrics::{MotionSample, RunMetrics, StrainExtremes};
pub use residual::{ConstraintResidual, ResidualsAtWorst, constraint_residuals};
pub use shape::{RestDeviation, ShapeReference, ShapeSample};
pub use skin::{
    SkinBindDistance, SkinBulge, skin_bind_distances, skin_bulges, skin_inside_vertices,
    skinned_surface,
};
pub use verdict::{Measured, Thresholds, Verdict};

use crate::closest::{TargetSource, TargetSurface};
use crate::muscle::Muscle;
use crate::solver::Solver;
use glam::Vec3;

/// Area of the cross-section of a closed, outward-oriented triangle mesh by
/// the plane through `point` with normal `normal`: the sum over triangles of
/// their directed cut segments, `½ Σ (a × b)·n̂`. Units: m².
pub fn cross_section_area(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    point: Vec3,
    normal: Vec3,
) -> f32 {
    let n = normal.normalize_or_zero();
    let mut twice = 0.0f64;
    for t in triangles {
        let p = t.map(|i| positions[i as usize] - point);
        let d = p.map(|v| v.dot(n));
        // Directed cut segment: from where the triangle's boundary (in its
        // own order) goes up through the plane to where it comes back down.
        // Neighbours traverse a shared edge the other way, so the segments
        // chain into closed loops whose signed areas add up.
        let mut up = None;
        let mut down = None;
        for e in 0..3 {
            let (a, b) = (e, (e + 1) % 3);
            let crossing = || p[a] + (p[b] - p[a]) * (d[a] / (d[a] - d[b]));
            if d[a] <= 0.0 && d[b] > 0.0 {
                up = Some(crossing());
            } else if d[a] > 0.0 && d[b] <= 0.0 {
                down = Some(crossing());
            }
        }
        if let (Some(a), Some(b)) = (up, down) {
            twice += f64::from(a.cross(b).dot(n));
        }
    }
    (twice.abs() * 0.5) as f32
}

/// A muscle's belly cross-section: the plane through the internal point
/// farthest (in rings) from the roots — the middle of the belly for roots at
/// both tendon tips — normal to the medulla there (the line between that
/// point's branch neighbours), in the current pose. Without an internal
/// structure: the plane through the surface centroid normal to the line
/// between the first two roots.
pub fn belly_cross_section(solver: &Solver, muscle: usize) -> f32 {
    let m = &solver.muscles()[muscle];
    let surface = &m.x[..m.surface_count];
    let s = &m.structure;
    let belly = (0..s.points.len()).max_by_key(|&k| (s.levels[k], std::cmp::Reverse(k)));
    let (point, axis) = match belly {
        Some(k) => {
            let at = |i: u32| m.x[m.surface_count + i as usize];
            let neighbours: Vec<u32> = s
                .branches
                .iter()
                .filter_map(|&[a, b]| {
                    (a as usize == k)
                        .then_some(b)
                        .or((b as usize == k).then_some(a))
                })
                .collect();
            let here = at(k as u32);
            let axis = match neighbours.as_slice() {
                [a, b, ..] => at(*b) - at(*a),
                [a] => here - at(*a),
                [] => Vec3::X,
            };
            (here, axis)
        }
        None => {
            let centroid = surface.iter().copied().sum::<Vec3>() / surface.len().max(1) as f32;
            let axis = match m.roots.as_slice() {
                [a, b, ..] => m.x[*b as usize] - m.x[*a as usize],
                _ => Vec3::X,
            };
            (centroid, axis)
        }
    };
    cross_section_area(surface, &m.mesh.triangles, point, axis)
}

/// How far apart `m`'s attachments are now against at rest: the distance
/// between the centroids of its two attachment groups (a group per bone,
/// or the world) that lie farthest apart at rest, over that distance at
/// rest. It is what the attachments alone ask of the muscle's length: the
/// edges along its line stretch (above 1) or shorten (below 1) by at least
/// this much on average, whatever the solver does. `None` for a muscle
/// attached to fewer than two bones.
pub fn attachment_span(m: &Muscle) -> Option<f32> {
    let groups = |positions: &[Vec3]| -> Vec<Vec3> {
        let points = m
            .attachments
            .iter()
            .map(|a| (a.bone, positions[a.vertex.index()]));
        crate::muscle::group_centroids(points)
            .into_iter()
            .map(|g| g.1)
            .collect()
    };
    let (rest, i, j) = crate::muscle::farthest_pair(&groups(&m.rest))?;
    let now = groups(&m.x);
    Some(now[i].distance(now[j]) / rest)
}

/// Distance of every attached vertex from its goal: its bone point, turned
/// about its tendon's tip where the muscle's held line pivots
/// ([`crate::muscle::MuscleParams::tendon_pivot`]). Units: m (scene units
/// ÷ [`crate::SolverSettings::length_unit`]), as every figure here.
pub fn attachment_errors(solver: &Solver) -> impl Iterator<Item = f32> + '_ {
    let bones = solver.bones();
    solver.muscles().iter().flat_map(move |m| {
        let pose =
            |bone: Option<usize>| bone.map_or(glam::Affine3A::IDENTITY, |b| bones[b].transform);
        let mut goals: Vec<glam::Vec3> = m
            .attachments
            .iter()
            .map(|a| pose(a.bone).transform_point3(a.vertex_local))
            .collect();
        if let Some(line) = m.hold_line.as_ref().filter(|_| m.params.tendon_pivot > 0.0) {
            let now = line.pose(
                &|b| bones[b].transform,
                crate::muscle::LineShape::of(&m.params),
            );
            let mut internal: Vec<glam::Vec3> = m
                .attachments
                .iter()
                .filter(|a| a.internal_particle.is_some())
                .map(|a| pose(a.bone).transform_point3(a.internal_local))
                .collect();
            line.turn_attachments(&now, &m.attachments, &mut goals, &mut internal);
        }
        m.attachments
            .iter()
            .zip(goals)
            .map(move |(a, goal)| m.x[a.vertex.index()].distance(goal) / m.length_unit)
    })
}

/// Per muscle, its surface vertices deeper than `depth` (m) inside any bone mesh.
/// The closest-point test proposes, the winding number confirms.
pub fn penetrating_vertices(solver: &Solver, depth: f32) -> Vec<usize> {
    let bones: Vec<_> = solver
        .targets()
        .iter()
        .filter(|t| matches!(t.source, TargetSource::Bone(_)))
        .collect();
    solver
        .muscles()
        .iter()
        .map(|m| {
            let depth = depth * m.length_unit;
            m.x[..m.surface_count]
                .iter()
                .filter(|&&x| bones.iter().any(|b| inside_by(b, x, depth)))
                .count()
        })
        .collect()
}

/// Whether `x` is deeper than `depth` inside `target` (its nearest point's
/// side, confirmed by the winding number; outside its box is outside).
fn inside_by(target: &TargetSurface, x: Vec3, depth: f32) -> bool {
    target.lower_bound(x) == 0.0
        && target
            .closest_within(x, None, f32::INFINITY)
            .is_some_and(|h| h.signed_distance < -depth && target.contains(x))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::primitives::MeshGenerator;

    #[test]
    fn cross_section_of_an_ellipsoid_matches_pi_b_c() {
        let m = MeshGenerator::Ellipsoid {
            center: Vec3::ZERO,
            radii: Vec3::new(0.1, 0.02, 0.03),
            segments: 64,
            stacks: 64,
        }
        .build("e")
        .unwrap();
        let a = cross_section_area(&m.positions, &m.triangles, Vec3::ZERO, Vec3::X);
        let exact = std::f32::consts::PI * 0.02 * 0.03;
        assert!((a - exact).abs() / exact < 0.01, "{a} vs {exact}");
        // Tilted plane through the centre: larger, still finite and positive.
        let b = cross_section_area(
            &m.positions,
            &m.triangles,
            Vec3::ZERO,
            Vec3::new(1.0, 1.0, 0.0),
        );
        assert!(b > a);
    }
}
