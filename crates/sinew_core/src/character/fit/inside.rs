//! Pulling fitted soft tissue inside the character's skin: a slim
//! character's limbs are thinner than the anatomy's muscles scaled by bone
//! length, so the fit shrink-wraps what sticks out.

use super::spread::{spread_moves, spread_rounds, vertex_neighbours};
use super::{FittedGeometry, SkinVolume};
use crate::closest::{TargetSource, TargetSurface};
use crate::solver::Solver;
use glam::Vec3;

/// How [`SkinVolume::pull_inside`] moves a surface in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PullInside {
    /// Depth under the skin a pulled vertex goes to (the thinnest fat
    /// layer). Units: m. Default: 0.003.
    pub margin: f32,
    /// Rounds of pull and spread; each round pulls what is still outside.
    /// Default: 30.
    pub rounds: u32,
    /// Smoothing passes spreading a round's pulls to the neighbouring
    /// vertices (so a muscle is dented smoothly, not creased). Default: 6.
    pub spread: u32,
    /// Share of its neighbours' mean pull a vertex takes per spread pass,
    /// in `[0, 1)`: how far the dent reaches. Default: 0.8.
    pub falloff: f32,
    /// Distance a vertex is pushed out of a bone to, when bones are given.
    /// Units: m. Default: 0.001.
    pub bone_clearance: f32,
}

impl Default for PullInside {
    fn default() -> Self {
        Self {
            margin: 0.003,
            rounds: 30,
            spread: 6,
            falloff: 0.8,
            bone_clearance: 0.001,
        }
    }
}

/// What [`SkinVolume::pull_inside`] did to one surface.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PullReport {
    /// Vertices outside the skin before.
    pub outside_before: usize,
    /// Vertices outside the skin after.
    pub outside_after: usize,
    /// Largest distance a vertex moved. Units: m.
    pub largest_move: f32,
    /// Triangles whose normal turned by more than 90° (folded).
    pub folded: usize,
}

impl PullReport {
    /// Adds another surface's figures.
    pub fn add(&mut self, other: &Self) {
        self.outside_before += other.outside_before;
        self.outside_after += other.outside_after;
        self.largest_move = self.largest_move.max(other.largest_move);
        self.folded += other.folded;
    }
}

impl SkinVolume {
    /// Moves a surface (`points`, connected by `triangles`) inside the
    /// skin, `options.margin` under it, in three steps: the whole surface
    /// shifts inwards by its outside vertices' mean pull (keeping its
    /// shape); then it narrows about its long axis (keeping its length: a
    /// slim character's muscles are thinner) to the widest cross-section
    /// that has at most 1 % more of its vertices outside than the narrowest
    /// tried (half width); then what still sticks out is pulled in along the
    /// skin's normal, each pull spread over the neighbouring vertices with
    /// a falloff, in rounds until nothing is outside or the rounds are spent.
    /// Vertices deep inside and far from any pulled vertex move only with
    /// the first two steps.
    ///
    /// With `bones` (the fitted bones as one volume), vertices inside a bone
    /// are also pushed out to `options.bone_clearance` above it, where that
    /// keeps them inside the skin (the skin wins where the two disagree).
    pub fn pull_inside(
        &self,
        points: &mut [Vec3],
        triangles: &[[u32; 3]],
        options: &PullInside,
        bones: Option<&SkinVolume>,
    ) -> PullReport {
        let normals_before: Vec<Vec3> = triangles
            .iter()
            .map(|t| triangle_normal(points, t))
            .collect();
        let start = points.to_vec();
        let mut report = PullReport {
            outside_before: self.count_outside(points),
            ..PullReport::default()
        };
        if report.outside_before > 0 {
            self.shift_inside(points, options.margin);
            self.narrow_inside(points, options.margin);
            let neighbours = vertex_neighbours(points.len(), triangles);
            let pull = |p: Vec3| self.pull_of(p, options.margin);
            // Into the skin; under every skin vertex (a coarse surface can
            // cross a finer skin between its own vertices); out of the bones
            // where that stays inside the skin; a few times over.
            let push = |p: Vec3| {
                let out = bones?.push_of(p, options.bone_clearance)?;
                (self.outside_by(p + out) < 0.0).then_some(out)
            };
            // The skin vertices it can reach (it only moves inwards).
            let (lo, hi) = points.iter().fold(
                (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
                |(lo, hi), &p| (lo.min(p), hi.max(p)),
            );
            let reach = Vec3::splat(options.margin + 0.01);
            let near: Vec<Vec3> = (self.surface.positions().iter().copied())
                .filter(|s| s.cmpge(lo - reach).all() && s.cmple(hi + reach).all())
                .collect();
            for _ in 0..3 {
                spread_moves(points, &neighbours, options, pull);
                if !near.is_empty() {
                    // A few rounds: each one tests every near skin vertex.
                    let few = PullInside {
                        rounds: options.rounds.min(4),
                        ..*options
                    };
                    spread_rounds(points, &neighbours, &few, |points, _| {
                        below_skin_vertices(&near, points, triangles, options.margin)
                    });
                }
                if bones.is_some() {
                    spread_moves(points, &neighbours, options, push);
                }
            }
            spread_moves(points, &neighbours, options, pull);
        }
        report.outside_after = self.count_outside(points);
        report.largest_move = points
            .iter()
            .zip(&start)
            .map(|(p, s)| p.distance(*s))
            .fold(0.0, f32::max);
        report.folded = triangles
            .iter()
            .zip(&normals_before)
            .filter(|(t, before)| triangle_normal(points, t).dot(**before) < 0.0)
            .count();
        report
    }

    /// How far in (m) and which way a vertex must go to be `margin` under
    /// this surface (`None` where it already is).
    fn pull_of(&self, p: Vec3, margin: f32) -> Option<Vec3> {
        let hit = self.closest(p)?;
        let depth = hit.signed_distance + margin;
        (depth > 0.0).then(|| -depth * Vec3::from(hit.normal))
    }

    /// How far out (m) and which way a vertex inside this surface, or
    /// closer than `clearance` above it, must go to be `clearance` above it
    /// (`None` where it already is).
    fn push_of(&self, p: Vec3, clearance: f32) -> Option<Vec3> {
        let hit = self.closest(p)?;
        let short = clearance - hit.signed_distance;
        (short > 0.0).then(|| short * Vec3::from(hit.normal))
    }
}

/// How deep inside a fitted surface a skin vertex is looked for. Units: m.
const DEEPEST: f32 = 0.02;

/// Per vertex of a surface (`points`, `triangles`), how far in (m) to go so
/// that none of the `skin` vertices is inside it or closer than `margin`
/// above it: the corners of the surface's triangle nearest to such a skin
/// vertex go in along the surface's normal there (the largest move a corner
/// is asked for).
fn below_skin_vertices(
    skin: &[Vec3],
    points: &[Vec3],
    triangles: &[[u32; 3]],
    margin: f32,
) -> Vec<Option<Vec3>> {
    let mut moves: Vec<Option<Vec3>> = vec![None; points.len()];
    if triangles.is_empty() {
        return moves;
    }
    let mut surface = TargetSurface::new(
        "fitted surface",
        TargetSource::Bone(0),
        points.to_vec(),
        triangles.to_vec(),
    );
    surface.set_transform(glam::Affine3A::IDENTITY);
    for &skin in skin {
        if surface.lower_bound(skin) > margin {
            continue;
        }
        let Some(hit) = surface.closest_within(skin, None, margin.max(0.0) + 1.0) else {
            continue;
        };
        // Too close above it, or inside it (the side of the nearest point's
        // normal, confirmed by the winding number — costly, so only up to
        // `DEEPEST` in).
        let short = margin - hit.signed_distance;
        let sd = hit.signed_distance;
        if short <= 0.0 || sd < -DEEPEST || (sd < 0.0 && !surface.contains(skin)) {
            continue;
        }
        let step = -short * Vec3::from(hit.normal);
        for &corner in &surface.triangles()[hit.triangle as usize] {
            let slot = &mut moves[corner as usize];
            if slot.is_none_or(|m| m.length_squared() < step.length_squared()) {
                *slot = Some(step);
            }
        }
    }
    moves
}

impl SkinVolume {
    /// Shifts `points` rigidly by their vertices' mean pull, in rounds,
    /// while that lowers the number of vertices short of `margin` inside.
    fn shift_inside(&self, points: &mut [Vec3], margin: f32) {
        let n = points.len() as f32;
        let mut short = usize::MAX;
        for _ in 0..8 {
            let pulls: Vec<Vec3> = points
                .iter()
                .filter_map(|&p| self.pull_of(p, margin))
                .collect();
            if pulls.len() >= short || pulls.is_empty() {
                break;
            }
            short = pulls.len();
            let shift = pulls.iter().sum::<Vec3>() / n;
            points.iter_mut().for_each(|p| *p += shift);
        }
    }

    /// Scales `points` about their long axis (across it only) to the widest
    /// of 100 %, 95 %, … 50 % that has at most 1 % of the vertices more
    /// outside (`margin` under the skin) than the narrowest.
    fn narrow_inside(&self, points: &mut [Vec3], margin: f32) {
        let Some((centre, direction)) = long_axis(points) else {
            return;
        };
        let scaled = |s: f32| {
            points.iter().map(move |&p| {
                let on_axis = centre + (p - centre).dot(direction) * direction;
                on_axis + s * (p - on_axis)
            })
        };
        let short = |s: f32| {
            scaled(s)
                .filter(|&p| self.pull_of(p, margin).is_some())
                .count()
        };
        let widths: Vec<f32> = (0..=10).map(|k| 1.0 - 0.05 * k as f32).collect();
        let counts: Vec<usize> = widths.iter().map(|&s| short(s)).collect();
        let fewest = counts.iter().copied().min().unwrap_or(0);
        let allowed = fewest + points.len().div_ceil(100);
        let width = widths
            .iter()
            .zip(&counts)
            .find(|&(_, &c)| c <= allowed)
            .map_or(1.0, |(&s, _)| s);
        let narrowed: Vec<Vec3> = scaled(width).collect();
        points.copy_from_slice(&narrowed);
    }
}

/// The line through the centroid of `points` along their principal
/// direction (`None` for fewer than two distinct points).
fn long_axis(points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    if points.len() < 2 {
        return None;
    }
    let centre = points.iter().sum::<Vec3>() / points.len() as f32;
    let mut covariance = glam::Mat3::ZERO;
    for &p in points {
        let d = p - centre;
        covariance += glam::Mat3::from_cols(d * d.x, d * d.y, d * d.z);
    }
    // Power iteration from the direction of the farthest point.
    let far = points
        .iter()
        .map(|&p| p - centre)
        .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))?;
    let mut direction = far.try_normalize()?;
    for _ in 0..32 {
        direction = (covariance * direction).try_normalize()?;
    }
    Some((centre, direction))
}

fn triangle_normal(points: &[Vec3], t: &[u32; 3]) -> Vec3 {
    let [a, b, c] = t.map(|i| points.get(i as usize).copied().unwrap_or_default());
    (b - a).cross(c - a)
}

impl FittedGeometry {
    /// Pulls the fitted bones (`bones`' options) and then the muscles
    /// (`muscles`', kept out of the pulled bones) inside `skin`
    /// ([`SkinVolume::pull_inside`]); `solver` is the one the geometry came
    /// from (its surfaces' triangles). Returns what it did to the muscles
    /// and to the bones.
    pub fn pull_inside(
        &mut self,
        solver: &Solver,
        skin: &SkinVolume,
        muscles: &PullInside,
        bones: &PullInside,
    ) -> [PullReport; 2] {
        let mut report = [PullReport::default(); 2];
        let (mut all_points, mut all_triangles) = (Vec::new(), Vec::new());
        for (b, points) in &mut self.bones {
            let Some(target) = solver.bones()[*b].target else {
                continue;
            };
            let triangles = solver.targets()[target].triangles();
            report[1].add(&skin.pull_inside(points, triangles, bones, None));
            let offset = all_points.len() as u32;
            all_triangles.extend(triangles.iter().map(|t| t.map(|i| i + offset)));
            all_points.extend_from_slice(points);
        }
        let bone_volume = SkinVolume::from_surface("fitted bones", all_points, all_triangles);
        for (points, m) in self.muscles.iter_mut().zip(solver.muscles()) {
            let triangles = &m.mesh.triangles;
            report[0].add(&skin.pull_inside(points, triangles, muscles, Some(&bone_volume)));
        }
        report
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::primitives::MeshGenerator;

    fn ellipsoid(center: Vec3, radii: Vec3, segments: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mesh = MeshGenerator::Ellipsoid {
            center,
            radii,
            segments,
            stacks: segments,
        }
        .build("test")
        .unwrap();
        (mesh.positions.clone(), mesh.triangles.clone())
    }

    /// A "limb": a long ellipsoid skin of radius 4 cm; a "muscle" 2.5 cm
    /// thick lying 2.5 cm off its axis sticks out of it.
    fn limb_and_muscle() -> (SkinVolume, Vec<Vec3>, Vec<[u32; 3]>) {
        let (skin, skin_triangles) = ellipsoid(Vec3::ZERO, Vec3::new(0.4, 0.04, 0.04), 32);
        let skin = SkinVolume::from_surface("limb", skin, skin_triangles);
        let (muscle, triangles) = ellipsoid(
            Vec3::new(0.0, 0.025, 0.0),
            Vec3::new(0.15, 0.025, 0.025),
            12,
        );
        (skin, muscle, triangles)
    }

    #[test]
    fn a_muscle_sticking_out_is_pulled_in_without_folding() {
        let (skin, mut muscle, triangles) = limb_and_muscle();
        let report = skin.pull_inside(&mut muscle, &triangles, &PullInside::default(), None);
        assert!(report.outside_before > 20, "{report:?}");
        assert_eq!(report.outside_after, 0, "{report:?}");
        assert_eq!(report.folded, 0, "{report:?}");
        // At least the margin under the skin, up to rounding.
        let deepest_miss = muscle
            .iter()
            .map(|&p| skin.outside_by(p))
            .fold(f32::NEG_INFINITY, f32::max);
        assert!(deepest_miss < -0.002, "{deepest_miss}");
        // It keeps its length (narrowed across its axis, not squashed).
        let length = |points: &[Vec3]| {
            let xs = points.iter().map(|p| p.x);
            xs.clone().fold(f32::NEG_INFINITY, f32::max) - xs.fold(f32::INFINITY, f32::min)
        };
        assert!((length(&muscle) - 0.3).abs() < 0.01, "{}", length(&muscle));
    }

    #[test]
    fn what_is_inside_does_not_move_and_bones_push_out() {
        let (skin, _, _) = limb_and_muscle();
        let (mut inside, triangles) = ellipsoid(Vec3::ZERO, Vec3::new(0.1, 0.01, 0.01), 10);
        let before = inside.clone();
        let report = skin.pull_inside(&mut inside, &triangles, &PullInside::default(), None);
        assert_eq!(report.outside_before, 0);
        assert_eq!(inside, before);
        // A "bone" along the axis: the pulled muscle stays out of it.
        let (bone, bone_triangles) = ellipsoid(Vec3::ZERO, Vec3::new(0.3, 0.012, 0.012), 16);
        let bone = SkinVolume::from_surface("bone", bone, bone_triangles);
        let (skin, mut muscle, triangles) = limb_and_muscle();
        let options = PullInside::default();
        skin.pull_inside(&mut muscle, &triangles, &options, Some(&bone));
        let in_bone = muscle.iter().filter(|&&p| bone.outside_by(p) < 0.0).count();
        let outside = muscle.iter().filter(|&&p| skin.outside_by(p) > 0.0).count();
        assert_eq!((in_bone, outside), (0, 0));
    }
}
