//! The muscle-from-path builder: a closed, manifold, outward-oriented
//! fusiform quad mesh swept along a smooth curve through a muscle's path
//! points (origin, via points, insertion), with its fibres along the path.
//!
//! - The curve is a centripetal Catmull–Rom spline through the points, so it
//!   passes through every site without overshooting at uneven spacing.
//! - Rings are spaced evenly by arc length and framed by parallel transport,
//!   so the quads do not twist along the path.
//! - The radius follows the spindle profile of [`crate::mesh::primitives`]:
//!   tendon radius at the tips, belly radius in the middle. The belly radius
//!   comes from the maximum isometric force (PCSA = F / σ, circular section)
//!   unless one is given.
//! - The two tips are single pole vertices on the first and last path points:
//!   they are the roots of the internal structure, so it runs along the path.

use crate::closest::TargetSurface;
use crate::error::ImportError;
use crate::mesh::SurfaceMesh;
use crate::mesh::primitives::{oriented_outward, perpendicular_basis, spindle, tube};
use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};
use std::f32::consts::{PI, TAU};

/// Specific tension used to turn force into cross-section. Units: Pa.
pub const SPECIFIC_TENSION: f32 = 0.35e6;

/// Shortest path segment accepted. Units: m.
pub const MIN_SEGMENT: f32 = 1e-5;

/// How finely and how thick a muscle is swept.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SweepOptions {
    /// Vertices around each ring (≥ 3).
    pub around: u32,
    /// Rings between the two tips (≥ 2). Vertex count is `around × rings + 2`.
    pub rings: u32,
    /// Belly radius; `None` derives it from the force. Units: m.
    pub radius: Option<f32>,
    /// Radius used when neither a radius nor a force is known. Units: m.
    pub fallback_radius: f32,
    /// Largest belly radius derived from a force. Units: m.
    pub max_radius: f32,
    /// Tendon radius as a fraction of the belly radius.
    pub tendon_ratio: f32,
}

impl Default for SweepOptions {
    fn default() -> Self {
        Self {
            around: 10,
            rings: 16,
            radius: None,
            fallback_radius: 0.01,
            max_radius: 0.03,
            tendon_ratio: 0.25,
        }
    }
}

impl SweepOptions {
    /// Options whose vertex count is close to `vertices` (at least 32), with
    /// rings about as far apart as vertices around a ring of a typical muscle.
    pub fn with_resolution(vertices: u32) -> Self {
        let v = vertices.max(32) as f32;
        let around = ((v / 1.6).sqrt().round() as u32).max(6);
        let rings = (((v - 2.0) / around as f32).round() as u32).max(2);
        Self {
            around,
            rings,
            ..Self::default()
        }
    }

    /// Belly radius for a muscle of maximum isometric force `force` (N).
    pub fn belly_radius(&self, force: Option<f32>) -> f32 {
        self.radius.unwrap_or_else(|| {
            force.map_or(self.fallback_radius, |f| {
                (f / SPECIFIC_TENSION / PI).sqrt().min(self.max_radius)
            })
        })
    }
}

/// A swept muscle.
#[derive(Clone, Debug)]
pub struct SweptMuscle {
    /// The surface.
    pub mesh: SurfaceMesh,
    /// Unit fibre direction per vertex (the curve's tangent).
    pub fibers: Vec<Vec3>,
    /// Pole vertex at the first path point (origin).
    pub first_tip: u32,
    /// Pole vertex at the last path point (insertion).
    pub last_tip: u32,
    /// Vertices of each ring, origin to insertion.
    pub rings: Vec<Vec<u32>>,
    /// Belly radius used. Units: m.
    pub belly_radius: f32,
    /// Length of the curve. Units: m.
    pub length: f32,
    /// Centre-line point of each vertex's ring (the tips' own positions).
    pub centers: Vec<Vec3>,
}

/// Checks a path and returns it without repeated points.
fn checked_path(name: &str, points: &[Vec3]) -> Result<Vec<Vec3>, ImportError> {
    let err = |reason: String| ImportError::Path {
        muscle: name.to_string(),
        reason,
    };
    if points.len() < 2 {
        return Err(err(format!(
            "path has {} point(s); a muscle needs at least an origin and an insertion",
            points.len()
        )));
    }
    if let Some(i) = points.iter().position(|p| !p.is_finite()) {
        return Err(err(format!("path point {i} is not finite")));
    }
    for (i, w) in points.windows(2).enumerate() {
        if w[0].distance(w[1]) < MIN_SEGMENT {
            return Err(err(format!(
                "path segment {i} (points {i} and {}) has zero length",
                i + 1
            )));
        }
    }
    Ok(points.to_vec())
}

/// A dense polyline along the centripetal Catmull–Rom spline through `points`.
fn spline(points: &[Vec3], per_segment: usize) -> Vec<Vec3> {
    let n = points.len();
    let at = |i: isize| -> Vec3 {
        if i < 0 {
            2.0 * points[0] - points[1]
        } else if i as usize >= n {
            2.0 * points[n - 1] - points[n - 2]
        } else {
            points[i as usize]
        }
    };
    let mut out = vec![points[0]];
    for s in 0..n - 1 {
        let (p0, p1, p2, p3) = (
            at(s as isize - 1),
            at(s as isize),
            at(s as isize + 1),
            at(s as isize + 2),
        );
        // Centripetal knots: t_{k+1} = t_k + |Δp|^½.
        let knot = |a: Vec3, b: Vec3| a.distance(b).sqrt().max(1e-6);
        let t1 = knot(p0, p1);
        let t2 = t1 + knot(p1, p2);
        let t3 = t2 + knot(p2, p3);
        for k in 1..=per_segment {
            let t = t1 + (t2 - t1) * k as f32 / per_segment as f32;
            let a1 = p0 * ((t1 - t) / t1) + p1 * (t / t1);
            let a2 = p1 * ((t2 - t) / (t2 - t1)) + p2 * ((t - t1) / (t2 - t1));
            let a3 = p2 * ((t3 - t) / (t3 - t2)) + p3 * ((t - t2) / (t3 - t2));
            let b1 = a1 * ((t2 - t) / t2) + a2 * (t / t2);
            let b2 = a2 * ((t3 - t) / (t3 - t1)) + a3 * ((t - t1) / (t3 - t1));
            out.push(b1 * ((t2 - t) / (t2 - t1)) + b2 * ((t - t1) / (t2 - t1)));
        }
    }
    out
}

/// Points at arc-length fractions `fractions` along a polyline, with tangents.
fn resample(polyline: &[Vec3], fractions: &[f32]) -> (Vec<Vec3>, Vec<Vec3>, f32) {
    let mut cumulative = vec![0.0f32];
    for w in polyline.windows(2) {
        cumulative.push(cumulative.last().unwrap() + w[0].distance(w[1]));
    }
    let total = *cumulative.last().unwrap();
    let mut points = Vec::with_capacity(fractions.len());
    let mut tangents = Vec::with_capacity(fractions.len());
    let mut seg = 0;
    for &f in fractions {
        let s = f * total;
        while seg + 2 < cumulative.len() && cumulative[seg + 1] < s {
            seg += 1;
        }
        let span = (cumulative[seg + 1] - cumulative[seg]).max(1e-12);
        let u = ((s - cumulative[seg]) / span).clamp(0.0, 1.0);
        points.push(polyline[seg].lerp(polyline[seg + 1], u));
        tangents.push((polyline[seg + 1] - polyline[seg]).normalize_or_zero());
    }
    (points, tangents, total)
}

/// Sweeps a muscle along `points` (world, metres). `force` (N) sets the
/// belly radius unless `options.radius` does.
pub fn sweep_path(
    name: &str,
    points: &[Vec3],
    force: Option<f32>,
    options: &SweepOptions,
) -> Result<SweptMuscle, ImportError> {
    sweep_path_clear_of(name, points, force, options, &|c, _, r, _| (c, r))
}

/// [`sweep_path`] with each ring placed by `clear(centre, normal, radius,
/// previous)`, which returns the ring's centre and radius (`previous`: how
/// far the ring before it was moved), e.g. out of bones: a path
/// through a bone (a tendon that wraps around it in the source model) then
/// runs beside it and the muscle does not enclose the bone. `normal` is the
/// curve's tangent at the ring, the normal of the ring's plane: a centre
/// moved within that plane leaves the rings in the order and planes the
/// curve gave them, so a surface swept along a straight path cannot cross
/// itself, however far its rings move aside.
pub fn sweep_path_clear_of(
    name: &str,
    points: &[Vec3],
    force: Option<f32>,
    options: &SweepOptions,
    clear: &dyn Fn(Vec3, Vec3, f32, Vec3) -> (Vec3, f32),
) -> Result<SweptMuscle, ImportError> {
    let err = |reason: String| ImportError::Path {
        muscle: name.to_string(),
        reason,
    };
    if options.around < 3 || options.rings < 2 {
        return Err(err(format!(
            "resolution around = {}, rings = {}: need around ≥ 3 and rings ≥ 2",
            options.around, options.rings
        )));
    }
    let belly = options.belly_radius(force);
    let tendon = belly * options.tendon_ratio;
    let positive = |r: f32| r > 0.0 && r.is_finite();
    if !positive(belly) || !positive(tendon) {
        return Err(err(format!(
            "radius {belly} (tendon ratio {}) must be > 0",
            options.tendon_ratio
        )));
    }
    let points = checked_path(name, points)?;
    let polyline = spline(&points, 24);
    let rings = options.rings as usize;
    let fractions: Vec<f32> = (0..rings + 2)
        .map(|i| i as f32 / (rings + 1) as f32)
        .collect();
    let (mut centers, mut tangents, length) = resample(&polyline, &fractions);
    if length < 4.0 * tendon {
        return Err(err(format!(
            "path is {length:.4} m long, too short for a muscle of radius {belly:.4} m"
        )));
    }
    // Tangents of the curve, by central differences: smooth along it.
    for i in 1..=rings {
        tangents[i] = (centers[i + 1] - centers[i - 1])
            .try_normalize()
            .unwrap_or(tangents[i]);
    }
    let mut radii = vec![0.0; rings + 2];
    let mut shift = Vec3::ZERO;
    for i in 1..=rings {
        let on_path = centers[i];
        let r = spindle(fractions[i], belly, tendon);
        (centers[i], radii[i]) = clear(on_path, tangents[i], r, shift);
        shift = centers[i] - on_path;
    }
    // Parallel-transported frame.
    let (mut u, _) = perpendicular_basis(tangents[0]);
    let mut positions = vec![centers[0]];
    let mut fibers = vec![tangents[0]];
    let mut ring_centers = vec![centers[0]];
    let mut ring_ids = Vec::with_capacity(rings);
    let mut previous = tangents[0];
    for i in 1..=rings {
        let t = tangents[i];
        u = Quat::from_rotation_arc(previous, t) * u;
        u = (u - t * u.dot(t)).normalize_or_zero();
        previous = t;
        let v = t.cross(u);
        let r = radii[i];
        let ring: Vec<u32> = (0..options.around)
            .map(|j| {
                let phi = TAU * j as f32 / options.around as f32;
                positions.push(centers[i] + r * (phi.cos() * u + phi.sin() * v));
                fibers.push(t);
                ring_centers.push(centers[i]);
                positions.len() as u32 - 1
            })
            .collect();
        ring_ids.push(ring);
    }
    let last_tip = positions.len() as u32;
    positions.push(centers[rings + 1]);
    fibers.push(tangents[rings + 1]);
    ring_centers.push(centers[rings + 1]);
    let polygons = oriented_outward(&positions, tube(&ring_ids, Some(0), Some(last_tip)));
    let mesh = SurfaceMesh::new(format!("<swept {name}>"), positions, &polygons)?;
    Ok(SweptMuscle {
        mesh,
        fibers,
        first_tip: 0,
        last_tip,
        rings: ring_ids,
        belly_radius: belly,
        length,
        centers: ring_centers,
    })
}

/// Moves every vertex found inside one of `bones` outwards along the ray
/// from its centre-line point (`centers[i]`) through it, to the first point
/// at least `margin` outside every bone. Moving along rays keeps a ring's
/// vertices in angular order, so the surface wraps the bone instead of
/// collapsing onto its nearest points. A vertex whose ray never leaves the
/// bones within [`MAX_PUSH`] goes to the nearest surface point instead.
/// Returns how many vertices moved.
pub fn push_out_of_bones(
    positions: &mut [Vec3],
    centers: &[Vec3],
    bones: &[&TargetSurface],
    margin: f32,
) -> usize {
    // Inside any bone (winding number), and the distance to the nearest surface.
    let inside = |p: Vec3| bones.iter().any(|b| b.contains(p));
    let distance = |p: Vec3| {
        bones
            .iter()
            .filter_map(|b| b.closest_within(p, None, f32::INFINITY))
            .map(|h| h.distance)
            .fold(f32::INFINITY, f32::min)
    };
    let mut moved = 0;
    for (i, p) in positions.iter_mut().enumerate() {
        if !inside(*p) {
            continue;
        }
        moved += 1;
        let c = centers[i];
        let offset = *p - c;
        // Sphere tracing: the ball of radius `distance` holds no surface, so
        // inside/outside can only change after a step that nears a surface.
        let found = offset.try_normalize().and_then(|d| {
            let mut s = offset.length();
            let end = s + MAX_PUSH;
            let mut is_inside = true;
            while s < end {
                let q = c + d * s;
                let gap = distance(q);
                if gap < PUSH_STEP {
                    s += PUSH_STEP;
                    is_inside = inside(c + d * s);
                    continue;
                }
                if !is_inside && gap >= margin {
                    return Some(q);
                }
                s += gap.max(PUSH_STEP);
            }
            None
        });
        *p = match found {
            Some(q) => q,
            None => {
                let mut q = *p;
                for b in bones {
                    if b.contains(q)
                        && let Some(hit) = b.closest_within(q, None, f32::INFINITY)
                    {
                        let point = Vec3::from(hit.point);
                        q = point + (q - point).normalize_or_zero() * -margin;
                    }
                }
                q
            }
        };
    }
    moved
}

/// Farthest a vertex is pushed along its ray. Units: m.
pub const MAX_PUSH: f32 = 0.05;

/// Ray-marching step of [`push_out_of_bones`]. Units: m.
const PUSH_STEP: f32 = 0.001;

#[cfg(test)]
mod tests {
    use super::*;

    fn bent_path() -> Vec<Vec3> {
        vec![
            Vec3::new(0.0, 0.3, 0.0),
            Vec3::new(0.02, 0.15, 0.01),
            Vec3::new(0.03, 0.0, 0.02),
            Vec3::new(0.0, -0.05, 0.05),
        ]
    }

    #[test]
    fn swept_muscle_is_closed_oriented_and_follows_the_path() {
        let options = SweepOptions::default();
        let m = sweep_path("biceps", &bent_path(), Some(400.0), &options).unwrap();
        m.mesh.check_closed_manifold().unwrap();
        assert!(m.mesh.volume() > 0.0);
        assert_eq!(
            m.mesh.vertex_count(),
            (options.around * options.rings + 2) as usize
        );
        // Tips on the end points; the curve goes through every site.
        assert!(m.mesh.positions[0].distance(bent_path()[0]) < 1e-6);
        assert!(m.mesh.positions[m.last_tip as usize].distance(bent_path()[3]) < 1e-6);
        let dense = spline(&bent_path(), 24);
        for p in bent_path() {
            assert!(dense.iter().any(|q| q.distance(p) < 1e-5));
        }
        // PCSA radius: sqrt(400 / 0.35e6 / π) ≈ 19.1 mm.
        assert!(
            (m.belly_radius - 0.01907).abs() < 1e-4,
            "{}",
            m.belly_radius
        );
        // Fibres are unit and point along the path.
        assert!(m.fibers.iter().all(|f| (f.length() - 1.0).abs() < 1e-4));
        assert!(m.fibers[0].dot(bent_path()[1] - bent_path()[0]) > 0.0);
    }

    #[test]
    fn resolution_sets_the_vertex_count() {
        for target in [100, 178, 400, 1000] {
            let o = SweepOptions::with_resolution(target);
            let v = o.around * o.rings + 2;
            assert!(
                (v as f32 - target as f32).abs() / (target as f32) < 0.1,
                "{target}: {v}"
            );
        }
    }

    #[test]
    fn bad_paths_are_rejected() {
        let o = SweepOptions::default();
        let e = sweep_path("m", &[Vec3::ZERO], None, &o).unwrap_err();
        assert!(e.to_string().contains("at least"), "{e}");
        let p = [Vec3::ZERO, Vec3::ZERO, Vec3::Y];
        let e = sweep_path("m", &p, None, &o).unwrap_err();
        assert!(e.to_string().contains("segment 0"), "{e}");
        let bad = SweepOptions {
            radius: Some(-1.0),
            ..o
        };
        let e = sweep_path("m", &bent_path(), None, &bad).unwrap_err();
        assert!(e.to_string().contains("radius"), "{e}");
    }

    #[test]
    fn vertices_inside_a_bone_are_pushed_out() {
        let bone = crate::mesh::primitives::MeshGenerator::Ellipsoid {
            center: Vec3::ZERO,
            radii: Vec3::splat(0.02),
            segments: 16,
            stacks: 16,
        }
        .build("bone")
        .unwrap();
        let target = TargetSurface::new(
            "bone",
            crate::closest::TargetSource::Bone(0),
            bone.positions.clone(),
            bone.triangles.clone(),
        );
        // A muscle whose middle runs through the bone.
        let path = [Vec3::new(-0.08, 0.005, 0.0), Vec3::new(0.08, 0.005, 0.0)];
        let m = sweep_path("m", &path, None, &SweepOptions::default()).unwrap();
        let mut positions = m.mesh.positions.clone();
        let moved = push_out_of_bones(&mut positions, &m.centers, &[&target], 0.001);
        assert!(moved > 0);
        for p in &positions {
            let hit = target.closest_within(*p, None, f32::INFINITY).unwrap();
            assert!(hit.signed_distance > -1e-4, "{p} is inside");
        }
        // Still a valid mesh: no faces collapsed to a point.
        let polys: Vec<Vec<u32>> = m.mesh.polygons().map(<[u32]>::to_vec).collect();
        SurfaceMesh::new("pushed", positions, &polys).unwrap();
    }

    fn ball(centre: Vec3, radius: f32) -> TargetSurface {
        let bone = crate::mesh::primitives::MeshGenerator::Ellipsoid {
            center: centre,
            radii: Vec3::splat(radius),
            segments: 24,
            stacks: 16,
        }
        .build("bone")
        .unwrap();
        TargetSurface::new(
            "bone",
            crate::closest::TargetSource::Bone(0),
            bone.positions.clone(),
            bone.triangles.clone(),
        )
    }

    #[test]
    fn rings_moved_aside_within_their_planes_leave_the_surface_uncrossed() {
        // A straight path through the top of a bone: its rings move up out
        // of the bone, each within its own plane, and the surface cannot
        // cross itself. Moved instead to a radius from the nearest bone
        // point in any direction, the rings leave their order along the
        // path and the surface crumples into itself.
        let bone = ball(Vec3::new(0.0, -0.012, 0.0), 0.02);
        let path = [Vec3::new(-0.05, 0.0, 0.0), Vec3::new(0.05, 0.0, 0.0)];
        let options = SweepOptions {
            radius: Some(0.012),
            ..SweepOptions::default()
        };
        let within = |c: Vec3, n: Vec3, r: f32, previous: Vec3| {
            crate::import::clearance::clear_ring(c, n, r, 0.25 * r, previous, 0.001, &[&bone])
        };
        let m = sweep_path_clear_of("m", &path, None, &options, &within).unwrap();
        assert_eq!(m.mesh.self_crossings(&m.mesh.positions), 0);
        assert!(m.mesh.positions.iter().all(|&p| !bone.contains(p)));
        let anywhere = |c: Vec3, _: Vec3, r: f32, _: Vec3| {
            let point = Vec3::from(bone.closest(c, None).unwrap().point);
            let out = (c - point).normalize() * if bone.contains(c) { -1.0 } else { 1.0 };
            (point + out * (r + 0.001), r)
        };
        let m = sweep_path_clear_of("m", &path, None, &options, &anywhere).unwrap();
        assert!(m.mesh.self_crossings(&m.mesh.positions) > 0);
    }
}
