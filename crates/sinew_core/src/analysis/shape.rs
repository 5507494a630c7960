//! Shape measures: whether a muscle keeps its shape.
//!
//! ```text
//! edge strain     |x_a − x_b| / |r_a − r_b|   over every mesh edge (the Fiber edges),
//!                 r = start-frame (rest) positions; min, max, p1 and p99 per frame
//! flipped         triangles folded against their neighbourhood — the area vector n_t
//!                 points against the sum of its edge neighbours' (n_t · Σ n_k < 0) —
//!                 or inverted against the medulla — n_t · (m_t − q̄), m_t its centroid
//!                 and q̄ the mean of its vertices' internal points, changed sign —
//!                 where neither held at rest: a surface
//!                 crumpled into shards, a vertex pushed through its muscle, a tip
//!                 turned through its ring
//! rest deviation  |x_v − B(t) B(0)⁻¹ r_v|, B the pose of the bone of v's nearest
//!                 attachment at rest (the world for world attachments), once the
//!                 motion has stopped
//! ```

use crate::muscle::Muscle;
use crate::solver::Bone;
use glam::{Affine3A, Vec3};
use std::collections::HashMap;

/// What a muscle's shape is compared with: its rest edge lengths, triangle
/// neighbourhoods and each vertex's rest position in its home bone's frame.
#[derive(Clone, Debug)]
pub struct ShapeReference {
    edges: Vec<[u32; 2]>,
    rest_length: Vec<f32>,
    /// Per triangle, the triangles across its three edges (`u32::MAX`: none).
    neighbours: Vec<[u32; 3]>,
    /// Triangles not folded at rest: only these can count as folded later.
    judged: Vec<bool>,
    /// Per triangle, the internal point (particle index) it is measured
    /// against for inversion, when it faced away from it at rest.
    medulla: Vec<Option<[u32; 3]>>,
    /// Per surface vertex: the bone of its nearest attachment (`None`: the
    /// world) and its rest position in that bone's rest frame.
    home: Vec<(Option<usize>, Vec3)>,
}

/// One frame's shape figures of one muscle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ShapeSample {
    /// Smallest edge length / rest length.
    pub strain_min: f32,
    /// Largest edge length / rest length.
    pub strain_max: f32,
    /// 1st percentile of edge length / rest length.
    pub strain_p1: f32,
    /// 99th percentile of edge length / rest length.
    pub strain_p99: f32,
    /// Triangles folded against their neighbours or inverted against the
    /// medulla (see the module docs).
    pub flipped: usize,
}

/// How far a muscle's surface is from its rest shape. Units: m.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RestDeviation {
    /// Largest vertex distance from its rest position.
    pub max: f32,
    /// Root mean square over the surface vertices.
    pub rms: f32,
    /// The vertex at `max`.
    pub worst_vertex: u32,
}

impl ShapeReference {
    /// The reference of `m` in its current (rest) state; `bones` give the
    /// attachments' bone poses now.
    pub fn new(m: &Muscle, bones: &[Bone]) -> Self {
        let rest = &m.rest;
        let rest_length = m
            .mesh
            .edges
            .iter()
            .map(|&[a, b]| rest[a as usize].distance(rest[b as usize]))
            .collect();
        let triangles = &m.mesh.triangles;
        let mut by_edge: HashMap<(u32, u32), u32> = HashMap::with_capacity(3 * triangles.len());
        for (t, tri) in triangles.iter().enumerate() {
            for k in 0..3 {
                by_edge.insert((tri[k], tri[(k + 1) % 3]), t as u32);
            }
        }
        let neighbours: Vec<[u32; 3]> = triangles
            .iter()
            .map(|tri| {
                std::array::from_fn(|k| {
                    by_edge
                        .get(&(tri[(k + 1) % 3], tri[k]))
                        .copied()
                        .unwrap_or(u32::MAX)
                })
            })
            .collect();
        let areas = area_vectors(triangles, rest);
        let judged = (0..triangles.len())
            .map(|t| fold_measure(t, &areas, &neighbours) > JUDGED)
            .collect();
        let n = m.surface_count as u32;
        let points = &m.structure.vertex_point;
        let medulla = triangles
            .iter()
            .zip(&areas)
            .map(|(tri, area)| {
                if m.structure.points.is_empty() || points.len() < m.surface_count {
                    return None;
                }
                let q = tri.map(|v| n + points[v as usize]);
                (inversion_measure(*tri, q, area, rest) > JUDGED).then_some(q)
            })
            .collect();
        let home = (0..m.surface_count)
            .map(|v| {
                let r = rest[v];
                let nearest = m.attachments.iter().min_by(|a, b| {
                    let da = rest[a.vertex.index()].distance_squared(r);
                    let db = rest[b.vertex.index()].distance_squared(r);
                    da.total_cmp(&db)
                });
                let bone = nearest.and_then(|a| a.bone);
                let pose = bone.map_or(Affine3A::IDENTITY, |b| bones[b].transform);
                (bone, pose.inverse().transform_point3(r))
            })
            .collect();
        Self {
            edges: m.mesh.edges.clone(),
            rest_length,
            neighbours,
            judged,
            medulla,
            home,
        }
    }

    /// The shape figures of `m` now (start-of-frame positions). `scratch`
    /// is reused between calls.
    pub fn sample(&self, m: &Muscle, scratch: &mut Vec<f32>) -> ShapeSample {
        scratch.clear();
        scratch.extend(
            self.edges
                .iter()
                .zip(&self.rest_length)
                .filter(|&(_, &rest)| rest > 0.0)
                .map(|(&[a, b], &rest)| m.x[a as usize].distance(m.x[b as usize]) / rest),
        );
        let mut sample = ShapeSample::default();
        if !scratch.is_empty() {
            let (lo, hi) = scratch
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &s| {
                    (lo.min(s), hi.max(s))
                });
            sample.strain_min = lo;
            sample.strain_max = hi;
            let n = scratch.len();
            let at = |scratch: &mut Vec<f32>, rank: usize| {
                *scratch
                    .select_nth_unstable_by(rank.min(n - 1), f32::total_cmp)
                    .1
            };
            sample.strain_p1 = at(scratch, n / 100);
            sample.strain_p99 = at(scratch, n - 1 - n / 100);
        }
        let areas = area_vectors(&m.mesh.triangles, &m.x);
        let triangles = &m.mesh.triangles;
        sample.flipped = (0..areas.len())
            .filter(|&t| {
                let folded = self.judged[t] && fold_measure(t, &areas, &self.neighbours) < 0.0;
                let inverted = self.medulla[t]
                    .is_some_and(|q| inversion_measure(triangles[t], q, &areas[t], &m.x) < 0.0);
                folded || inverted
            })
            .count();
        sample
    }

    /// How far `m`'s surface is from its rest positions carried by each
    /// vertex's home bone (`bones` at their current poses).
    pub fn rest_deviation(&self, m: &Muscle, bones: &[Bone]) -> RestDeviation {
        let mut deviation = RestDeviation::default();
        let mut sum = 0.0f64;
        for (v, &(bone, local)) in self.home.iter().enumerate() {
            let pose = bone.map_or(Affine3A::IDENTITY, |b| bones[b].transform);
            let d = m.x[v].distance(pose.transform_point3(local)) / m.length_unit;
            sum += f64::from(d * d);
            if d > deviation.max {
                deviation.max = d;
                deviation.worst_vertex = v as u32;
            }
        }
        deviation.rms = (sum / self.home.len().max(1) as f64).sqrt() as f32;
        deviation
    }
}

/// A triangle is judged for a fold (or an inversion) only where, at rest,
/// the cosine it measures exceeds this: a triangle nearly edge-on to its
/// neighbourhood or to the medulla at rest (a tendon tip) can tip past 90°
/// with no fold at all.
const JUDGED: f32 = 0.3;

/// The cosine between the triangle's normal and the direction from the mean
/// of its vertices' internal points `q` to its centroid: positive while the
/// triangle faces away from the medulla.
fn inversion_measure(tri: [u32; 3], q: [u32; 3], area: &Vec3, positions: &[Vec3]) -> f32 {
    let centre = q.iter().map(|&i| positions[i as usize]).sum::<Vec3>() / 3.0;
    let mid = tri.iter().map(|&i| positions[i as usize]).sum::<Vec3>() / 3.0;
    cosine(*area, mid - centre)
}

/// Cosine of the angle between `a` and `b` (0 when either is zero).
fn cosine(a: Vec3, b: Vec3) -> f32 {
    let d = a.length() * b.length();
    if d > 0.0 { a.dot(b) / d } else { 0.0 }
}

/// Area vectors `(b − a) × (c − a)` of the triangles at `positions`.
fn area_vectors(triangles: &[[u32; 3]], positions: &[Vec3]) -> Vec<Vec3> {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            (b - a).cross(c - a)
        })
        .collect()
}

/// The cosine between triangle `t`'s normal and the sum of its edge
/// neighbours' area vectors: negative when it faces against its
/// neighbourhood.
fn fold_measure(t: usize, areas: &[Vec3], neighbours: &[[u32; 3]]) -> f32 {
    let around: Vec3 = neighbours[t]
        .iter()
        .filter(|&&k| k != u32::MAX)
        .map(|&k| areas[k as usize])
        .sum();
    cosine(areas[t], around)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin;
    use std::path::Path;

    fn p1() -> crate::solver::Solver {
        builtin("P1").unwrap().instantiate(Path::new(".")).unwrap()
    }

    #[test]
    fn a_muscle_at_rest_has_unit_strain_no_fold_and_no_deviation() {
        let solver = p1();
        let m = &solver.muscles()[0];
        let reference = ShapeReference::new(m, solver.bones());
        let sample = reference.sample(m, &mut Vec::new());
        assert_eq!(sample.strain_min, 1.0);
        assert_eq!(sample.strain_max, 1.0);
        assert_eq!(sample.flipped, 0);
        assert_eq!(reference.rest_deviation(m, solver.bones()).max, 0.0);
    }

    #[test]
    fn a_stretched_edge_a_pushed_through_vertex_and_a_moved_vertex_are_seen() {
        let mut solver = p1();
        let reference = ShapeReference::new(&solver.muscles()[0], solver.bones());
        let m = solver.muscle_mut(0);
        // Vertex 45 sits on the oval's equator: push it through the far side.
        let v = 45;
        let centre = m.x[..m.surface_count].iter().copied().sum::<Vec3>() / m.surface_count as f32;
        m.x[v] = centre + (centre - m.x[v]) * 0.8;
        let sample = reference.sample(m, &mut Vec::new());
        assert!(sample.flipped > 0, "{sample:?}");
        assert!(sample.strain_max > 1.5, "{sample:?}");
        let deviation = reference.rest_deviation(&solver.muscles()[0], solver.bones());
        assert_eq!(deviation.worst_vertex, v as u32);
        assert!(deviation.max > 0.02, "{deviation:?}");
    }
}
