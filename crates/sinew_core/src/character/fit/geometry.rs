//! What a fit does to a solver's geometry, and the skin's inside.

use super::{AnatomyFit, Similarity};
use crate::character::SkinnedCharacter;
use crate::closest::{ClosestHit, TargetSource, TargetSurface};
use crate::solver::Solver;
use glam::{Affine3A, Vec3};

/// A solver's bones and muscles moved by an [`AnatomyFit`] (metres).
#[derive(Clone, Debug, PartialEq)]
pub struct FittedGeometry {
    /// Per bone with a mesh: `(bone index, its vertices in the world)`.
    pub bones: Vec<(usize, Vec<Vec3>)>,
    /// Per muscle, its surface vertices.
    pub muscles: Vec<Vec<Vec3>>,
}

impl AnatomyFit {
    /// `solver`'s bone meshes and muscle surfaces where the fit puts them:
    /// a bone's vertices by its body's similarity; a muscle vertex by the
    /// two anatomy segments nearest to it, blended by distance (a vertex on
    /// one segment's line moves with that segment alone), so muscles stay
    /// along the bones they lie on across bent joints.
    pub fn geometry(&self, solver: &Solver) -> FittedGeometry {
        let unit = solver.settings.length_unit;
        let bones = (0..solver.bones().len())
            .filter_map(|b| Some((b, self.bone_points(solver, b)?.collect())))
            .collect();
        let muscles = solver
            .muscles()
            .iter()
            .map(|m| {
                let bodies: Vec<usize> = m
                    .attachments
                    .iter()
                    .filter_map(|a| a.bone.and_then(|b| solver.bones()[b].body))
                    .collect();
                let candidates = self.segments_between(&bodies);
                m.surface_positions()
                    .iter()
                    .map(|&p| self.move_soft_point(p / unit, &candidates))
                    .collect()
            })
            .collect();
        FittedGeometry { bones, muscles }
    }

    /// Bone `bone`'s mesh vertices where the fit puts them (its body's
    /// similarity; metres), `None` for a bone without a mesh.
    fn bone_points<'a>(
        &self,
        solver: &'a Solver,
        bone: usize,
    ) -> Option<impl Iterator<Item = Vec3> + 'a> {
        let bone = &solver.bones()[bone];
        let target = &solver.targets()[bone.target?];
        let fit = bone.body.map_or(Similarity::IDENTITY, |b| self.body(b));
        let (pose, unit) = (bone.transform, solver.settings.length_unit);
        Some(
            target
                .positions()
                .iter()
                .map(move |&p| fit.apply(pose.transform_point3(p) / unit)),
        )
    }
}

impl AnatomyFit {
    /// The segments a muscle held by `bodies` can lie along: those of every
    /// body on the skeleton's paths between them (all segments when
    /// `bodies` is empty).
    pub fn segments_between(&self, bodies: &[usize]) -> Vec<usize> {
        let chain = |b: usize| {
            let mut up = vec![b];
            while let Some(p) = self.parents[*up.last().expect("not empty")] {
                up.push(p);
            }
            up
        };
        let mut on_path: Vec<usize> = Vec::new();
        for (k, &a) in bodies.iter().enumerate() {
            for &b in &bodies[k..] {
                let (up_a, up_b) = (chain(a), chain(b));
                let meet = up_a.iter().position(|x| up_b.contains(x));
                let meet_b = meet.and_then(|m| up_b.iter().position(|&y| y == up_a[m]));
                on_path.extend(&up_a[..=meet.unwrap_or(up_a.len() - 1)]);
                on_path.extend(&up_b[..=meet_b.unwrap_or(up_b.len() - 1)]);
            }
        }
        let mut segments: Vec<usize> = on_path
            .into_iter()
            .filter_map(|b| self.segment_of.get(b).copied().flatten())
            .collect();
        segments.sort_unstable();
        segments.dedup();
        if segments.is_empty() {
            (0..self.segments.len()).collect()
        } else {
            segments
        }
    }

    /// Where the fit puts a point of soft tissue at `p` (m): the two
    /// nearest of the `candidates` segments' similarities, blended by
    /// distance.
    pub fn move_soft_point(&self, p: Vec3, candidates: &[usize]) -> Vec3 {
        let distance = |(a, b): (Vec3, Vec3)| {
            let ab = b - a;
            let t = if ab.length_squared() > 0.0 {
                ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
            } else {
                0.0
            };
            p.distance(a + t * ab)
        };
        let mut nearest = [(f32::INFINITY, Similarity::IDENTITY); 2];
        for s in candidates.iter().filter_map(|&k| self.segments.get(k)) {
            let d = distance(s.line);
            if d < nearest[0].0 {
                nearest = [(d, s.similarity), nearest[0]];
            } else if d < nearest[1].0 {
                nearest[1] = (d, s.similarity);
            }
        }
        let [(d0, s0), (d1, s1)] = nearest;
        if !d1.is_finite() {
            return s0.apply(p);
        }
        let w1 = if d0 + d1 > 0.0 { d0 / (d0 + d1) } else { 0.0 };
        s0.apply(p).lerp(s1.apply(p), w1)
    }
}

impl AnatomyFit {
    /// Moves each segment named in `free` (the bodies a rig's joints do not
    /// place: the pelvis, the chest) along the character's depth axis (Z,
    /// front to back) to where the fewest of its bones' vertices are outside
    /// `skin`, searching ±`reach` metres in 5 mm steps (the smallest move
    /// among equals); the bodies that take its similarity move with it.
    /// Returns each moved segment's offset (m).
    pub fn settle_in_skin(
        &mut self,
        solver: &Solver,
        skin: &SkinVolume,
        free: &[String],
        reach: f32,
    ) -> Vec<(String, f32)> {
        let mut moved = Vec::new();
        for k in 0..self.segments.len() {
            if !free.contains(&self.segments[k].body) {
                continue;
            }
            // Its bones' vertices (every fourth), where the fit puts them now.
            let points: Vec<Vec3> = (0..solver.bones().len())
                .filter(|&b| {
                    solver.bones()[b]
                        .body
                        .and_then(|body| self.segment_of[body])
                        == Some(k)
                })
                .filter_map(|b| self.bone_points(solver, b))
                .flat_map(|points| points.step_by(4))
                .collect();
            if points.is_empty() {
                continue;
            }
            let steps = (reach / 0.005).round() as i32;
            let outside = |dz: f32| {
                let shift = Vec3::new(0.0, 0.0, dz);
                points
                    .iter()
                    .filter(|&&p| skin.outside_by(p + shift) > 0.0)
                    .count()
            };
            // Each offset's count once; the fewest outside, then the smallest move.
            let best = (-steps..=steps)
                .map(|s| s as f32 * 0.005)
                .map(|dz| (outside(dz), dz))
                .min_by(|a, b| a.0.cmp(&b.0).then(a.1.abs().total_cmp(&b.1.abs())))
                .map_or(0.0, |(_, dz)| dz);
            // Every body of the segment takes its similarity (`body`).
            self.segments[k].similarity.translation += Vec3::new(0.0, 0.0, best);
            moved.push((self.segments[k].body.clone(), best));
        }
        moved
    }
}

/// The volume inside a character's skin at its bind pose, for inside and
/// outside tests (the side of the closest skin point's normal; holes such
/// as the eyes' and mouth's are tolerated).
#[derive(Clone, Debug)]
pub struct SkinVolume {
    pub(super) surface: TargetSurface,
}

impl SkinVolume {
    /// The skin of `character` at its bind pose.
    pub fn new(character: &SkinnedCharacter) -> Self {
        Self::from_surface(
            format!("{} skin", character.name),
            character.positions.clone(),
            character.triangles.clone(),
        )
    }

    /// The inside of any closed surface (outward-facing triangles): the
    /// fitted bones, a test shape.
    pub fn from_surface(
        name: impl Into<String>,
        positions: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
    ) -> Self {
        let mut surface =
            TargetSurface::new(name.into(), TargetSource::Bone(0), positions, triangles);
        surface.set_transform(Affine3A::IDENTITY);
        Self { surface }
    }

    /// How far `p` is outside the skin (m; ≤ 0 inside).
    pub fn outside_by(&self, p: Vec3) -> f32 {
        self.closest(p)
            .map_or(f32::INFINITY, |hit| hit.signed_distance)
    }

    /// How many of `points` are outside the skin.
    pub fn count_outside(&self, points: &[Vec3]) -> usize {
        points.iter().filter(|&&p| self.outside_by(p) > 0.0).count()
    }

    /// The skin point closest to `p`, with its outward normal (`None` for
    /// a skin without triangles).
    pub fn closest(&self, p: Vec3) -> Option<ClosestHit> {
        self.surface.closest_within(p, None, f32::MAX)
    }
}
