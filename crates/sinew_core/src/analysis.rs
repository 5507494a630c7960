//! Measurements of a running simulation: the figures the anatomy scenes are
//! judged by (finiteness, attachment error, muscle–bone penetration, volume,
//! activation and belly cross-section), collected frame by frame.

use crate::solver::Solver;
use crate::target::TargetSource;
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

/// Distance of every attached vertex from its bone point.
pub fn attachment_errors(solver: &Solver) -> impl Iterator<Item = f32> + '_ {
    solver.muscles().iter().flat_map(move |m| {
        m.attachments.iter().map(move |a| {
            let pose = a
                .bone
                .map_or(glam::Affine3A::IDENTITY, |b| solver.bones()[b].transform);
            m.x[a.vertex as usize].distance(pose.transform_point3(a.vertex_local))
        })
    })
}

/// Per muscle, its surface vertices deeper than `depth` inside any bone mesh.
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
            m.x[..m.surface_count]
                .iter()
                .filter(|&&x| {
                    bones.iter().any(|b| {
                        // Outside the bone's box is outside the bone.
                        b.lower_bound(x) == 0.0
                            && b.closest_within(x, None, f32::INFINITY)
                                .is_some_and(|h| h.signed_distance < -depth && b.contains(x))
                    })
                })
                .count()
        })
        .collect()
}

/// Running figures over a simulation, one [`RunMetrics::observe`] per frame.
#[derive(Clone, Debug)]
pub struct RunMetrics {
    /// Frames observed.
    pub frames: u32,
    /// First frame with a NaN or infinite position, if any.
    pub first_non_finite: Option<u32>,
    /// Sum of attachment errors (for the mean). Units: m.
    pub attachment_error_sum: f64,
    /// Attachment error samples.
    pub attachment_samples: u64,
    /// Largest attachment error. Units: m.
    pub attachment_error_max: f32,
    /// Largest share of surface vertices deeper than [`RunMetrics::depth`] inside a bone.
    pub penetration_max: f32,
    /// Frame of that share.
    pub penetration_frame: u32,
    /// Penetration depth counted. Units: m.
    pub depth: f32,
    /// Per muscle: (min, max) of volume / rest volume.
    pub volume_ratio: Vec<(f64, f64)>,
    /// Per muscle: largest activation seen.
    pub activation_max: Vec<f32>,
    /// Per muscle: belly cross-section at rest. Units: m².
    pub rest_section: Vec<f32>,
    /// Per muscle: (activation, section / rest section) at its most active frame.
    pub section_at_peak: Vec<(f32, f32)>,
    /// Check penetration every this many frames (1 = every frame).
    pub penetration_every: u32,
    /// Per muscle: largest attachment error. Units: m.
    pub muscle_attachment_max: Vec<f32>,
    /// Per muscle: largest share of its vertices deeper than `depth` in a bone.
    pub muscle_penetration_max: Vec<f32>,
    /// Muscle of each attachment, in [`attachment_errors`] order.
    attachment_owner: Vec<usize>,
    /// Jiggle: sum of squared surface-vertex accelerations measured in the
    /// frame of each muscle's first attached bone, and the sample count.
    jiggle_sum: f64,
    jiggle_samples: u64,
    /// The last two frames' vertex positions in those bone frames.
    history: [Vec<glam::Vec3>; 2],
}

impl RunMetrics {
    /// Starts measuring `solver` in its current (rest) state.
    pub fn new(solver: &Solver, depth: f32) -> Self {
        let n = solver.muscles().len();
        Self {
            frames: 0,
            first_non_finite: None,
            attachment_error_sum: 0.0,
            attachment_samples: 0,
            attachment_error_max: 0.0,
            penetration_max: 0.0,
            penetration_frame: 0,
            depth,
            volume_ratio: vec![(f64::INFINITY, f64::NEG_INFINITY); n],
            activation_max: vec![0.0; n],
            rest_section: (0..n).map(|m| belly_cross_section(solver, m)).collect(),
            section_at_peak: vec![(0.0, 1.0); n],
            penetration_every: 1,
            muscle_attachment_max: vec![0.0; n],
            muscle_penetration_max: vec![0.0; n],
            attachment_owner: solver
                .muscles()
                .iter()
                .enumerate()
                .flat_map(|(i, m)| std::iter::repeat_n(i, m.attachments.len()))
                .collect(),
            jiggle_sum: 0.0,
            jiggle_samples: 0,
            history: [Vec::new(), Vec::new()],
        }
    }

    /// Records the state after a step.
    pub fn observe(&mut self, solver: &Solver) {
        let frame = self.frames;
        self.frames += 1;
        let finite = solver
            .muscles()
            .iter()
            .all(|m| m.x.iter().all(|p| p.is_finite()));
        if !finite && self.first_non_finite.is_none() {
            self.first_non_finite = Some(frame);
        }
        if !finite {
            return;
        }
        self.observe_jiggle(solver);
        for (i, e) in attachment_errors(solver).enumerate() {
            self.attachment_error_sum += f64::from(e);
            self.attachment_samples += 1;
            self.attachment_error_max = self.attachment_error_max.max(e);
            let m = self.attachment_owner[i];
            self.muscle_attachment_max[m] = self.muscle_attachment_max[m].max(e);
        }
        if frame.is_multiple_of(self.penetration_every.max(1)) {
            let inside = penetrating_vertices(solver, self.depth);
            let total: usize = solver.muscles().iter().map(|m| m.surface_count).sum();
            let share = inside.iter().sum::<usize>() as f32 / total.max(1) as f32;
            if share > self.penetration_max {
                self.penetration_max = share;
                self.penetration_frame = frame;
            }
            for ((worst, &n), m) in self
                .muscle_penetration_max
                .iter_mut()
                .zip(&inside)
                .zip(solver.muscles())
            {
                *worst = worst.max(n as f32 / m.surface_count.max(1) as f32);
            }
        }
        for (i, m) in solver.muscles().iter().enumerate() {
            let ratio = m.volume() / m.rest_volume();
            let (lo, hi) = &mut self.volume_ratio[i];
            *lo = lo.min(ratio);
            *hi = hi.max(ratio);
            let a = m.params.activation;
            if a > self.activation_max[i] {
                self.activation_max[i] = a;
                let section = belly_cross_section(solver, i);
                self.section_at_peak[i] = (a, section / self.rest_section[i].max(1e-12));
            }
        }
    }

    /// Secondary motion: the RMS acceleration of surface vertices in the frame
    /// of their muscle's first attached bone (so the bone's own motion does not
    /// count), by second differences over frames. 0 for a muscle that moves
    /// rigidly with its bone. Units: m/s².
    pub fn jiggle_rms(&self) -> f32 {
        (self.jiggle_sum / self.jiggle_samples.max(1) as f64).sqrt() as f32
    }

    fn observe_jiggle(&mut self, solver: &Solver) {
        let dt = solver.settings.dt * solver.settings.time_scale;
        let local: Vec<glam::Vec3> = solver
            .muscles()
            .iter()
            .flat_map(|m| {
                let frame = m
                    .attachments
                    .first()
                    .and_then(|a| a.bone)
                    .map_or(glam::Affine3A::IDENTITY, |b| solver.bones()[b].transform)
                    .inverse();
                m.x[..m.surface_count]
                    .iter()
                    .map(move |&x| frame.transform_point3(x))
            })
            .collect();
        let [older, old] = &self.history;
        if older.len() == local.len() && old.len() == local.len() {
            for ((a, b), c) in older.iter().zip(old).zip(&local) {
                let acceleration = (*c - 2.0 * *b + *a) / (dt * dt);
                self.jiggle_sum += f64::from(acceleration.length_squared());
                self.jiggle_samples += 1;
            }
        }
        self.history = [std::mem::take(&mut self.history[1]), local];
    }

    /// Mean attachment error. Units: m.
    pub fn attachment_error_mean(&self) -> f32 {
        (self.attachment_error_sum / self.attachment_samples.max(1) as f64) as f32
    }
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

    #[test]
    fn jiggle_is_zero_at_rest_and_positive_when_the_muscle_swings() {
        let mut still = crate::scene::builtin("P1").unwrap();
        still.settings.gravity = Vec3::ZERO;
        let mut solver = still.instantiate(std::path::Path::new(".")).unwrap();
        let mut metrics = RunMetrics::new(&solver, 0.002);
        for _ in 0..20 {
            solver.step();
            metrics.observe(&solver);
        }
        assert!(metrics.jiggle_rms() < 1e-3, "{}", metrics.jiggle_rms());
        let mut moving = crate::scene::builtin("T1").unwrap();
        moving.settings.gravity = Vec3::new(0.0, -9.81, 0.0);
        let mut solver = moving.instantiate(std::path::Path::new(".")).unwrap();
        let mut metrics = RunMetrics::new(&solver, 0.002);
        for _ in 0..30 {
            solver.step();
            metrics.observe(&solver);
        }
        assert!(metrics.jiggle_rms() > 0.1, "{}", metrics.jiggle_rms());
    }
}
