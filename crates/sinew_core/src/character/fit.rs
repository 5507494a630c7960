//! Fitting an anatomy (a scene's skeleton, bones and muscles) to a
//! character: a [`RigMap`] pairs the character's joints with the anatomy's
//! bodies, and each anatomical segment gets a similarity (uniform scale,
//! rotation, translation) that puts its body's origin on the paired joint
//! and its mapped children's origins in the direction, and at the distance,
//! of their joints ([`AnatomyFit::new`]).
//!
//! Both sides are in the same frame: metres, +Y up, facing +Z (glTF's, and
//! the imported anatomy's).

use super::{CharacterError, SkinnedCharacter};
use crate::closest::{TargetSource, TargetSurface};
use crate::skeleton::SkeletonRig;
use crate::solver::Solver;
use glam::{Affine3A, Quat, Vec3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Which anatomy body each character joint is: `(joint, body)` pairs.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigMap {
    /// `(character joint, anatomy body)`.
    pub pairs: Vec<(String, String)>,
    /// Mapped bodies whose origin is not where the character's rig puts its
    /// joint (a game rig's pelvis and chest joints sit mid-trunk, the
    /// anatomy's frames at the vertebrae): fitted to their mapped children
    /// only, their own origin left free.
    #[serde(default)]
    pub free: Vec<String>,
}

impl RigMap {
    /// The map for game-engine (Unreal-style) joint names — MakeHuman's
    /// game-engine rig, Mixamo-like rigs renamed to it — onto the myo-sim
    /// bodies of sinew's anatomy scenes (T7).
    pub fn game_engine() -> Self {
        // A game rig's spine joints run through the middle of the trunk,
        // the vertebrae behind it: the pelvis is fitted to the hips and the
        // chest (`spine_03`) to the thorax as a whole (clavicles and head),
        // their own origins free; the lumbar vertebrae go with the chest.
        let mut pairs = vec![
            ("pelvis", "pelvis"),
            ("spine_03", "torso"),
            ("head", "head"),
        ];
        let sided = [
            ("thigh", "femur"),
            ("calf", "tibia"),
            ("foot", "talus"),
            ("ball", "toes"),
            ("clavicle", "clavicle"),
            ("upperarm", "humerus"),
            ("lowerarm", "ulna"),
            ("hand", "lunate"),
        ];
        let mut owned: Vec<(String, String)> =
            pairs.drain(..).map(|(j, b)| (j.into(), b.into())).collect();
        for side in ["l", "r"] {
            for (joint, body) in sided {
                owned.push((format!("{joint}_{side}"), format!("{body}_{side}")));
            }
        }
        Self {
            pairs: owned,
            free: vec!["pelvis".into(), "torso".into()],
        }
    }

    /// Reads a map from a RON file (`RigMap(pairs: [("upperarm_r",
    /// "humerus_r"), …])`); errors name the file and the line.
    pub fn load(path: &Path) -> Result<Self, CharacterError> {
        let text = std::fs::read_to_string(path).map_err(|source| CharacterError::Io {
            file: path.to_path_buf(),
            source,
        })?;
        ron::from_str(&text).map_err(|e: ron::error::SpannedError| CharacterError::Json {
            file: path.to_path_buf(),
            element: format!("line {}, column {}", e.span.start.line, e.span.start.col),
            reason: e.code.to_string(),
        })
    }
}

/// `x ↦ scale · rotation · x + translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Similarity {
    /// Uniform scale (character length / anatomy length).
    pub scale: f32,
    /// Rotation.
    pub rotation: Quat,
    /// Translation (m).
    pub translation: Vec3,
}

impl Similarity {
    /// The identity.
    pub const IDENTITY: Self = Self {
        scale: 1.0,
        rotation: Quat::IDENTITY,
        translation: Vec3::ZERO,
    };

    /// The image of `p`.
    pub fn apply(&self, p: Vec3) -> Vec3 {
        self.scale * (self.rotation * p) + self.translation
    }
}

/// One mapped segment's fit.
#[derive(Clone, Debug, PartialEq)]
pub struct SegmentFit {
    /// The character joint.
    pub joint: String,
    /// The anatomy body.
    pub body: String,
    /// Its similarity.
    pub similarity: Similarity,
    /// Whether it was fitted to children (`false`: a leaf, which takes its
    /// parent segment's scale and rotation).
    pub fitted_to_children: bool,
    /// The anatomy segment at rest: from its body's origin to its mapped
    /// children's centre (a leaf: its origin twice). Metres.
    pub line: (Vec3, Vec3),
}

/// A similarity for every body of an anatomy.
#[derive(Clone, Debug, PartialEq)]
pub struct AnatomyFit {
    /// Per rig body (in the rig's order).
    pub bodies: Vec<Similarity>,
    /// The mapped segments, in the map's order.
    pub segments: Vec<SegmentFit>,
    /// Per rig body, its parent.
    parents: Vec<Option<usize>>,
    /// Per rig body, the segment (index in `segments`) whose similarity it
    /// takes.
    segment_of: Vec<Option<usize>>,
}

impl AnatomyFit {
    /// Fits `rig` (its bodies' world frames at rest: `rest`) to
    /// `character` through `map`. A mapped body's similarity puts its
    /// origin on its joint and turns and scales the segment to its nearest
    /// mapped descendants (their centroid); a mapped leaf keeps its parent
    /// segment's rotation and scale; an unmapped body takes its nearest
    /// mapped ancestor's similarity, or a mapped descendant's when it has no
    /// mapped ancestor. Errors name a joint the character lacks or a body
    /// the anatomy lacks.
    pub fn new(
        character: &SkinnedCharacter,
        rig: &SkeletonRig,
        rest: &[Affine3A],
        map: &RigMap,
    ) -> Result<Self, CharacterError> {
        let invalid = |element: String, reason: String| CharacterError::Invalid {
            character: character.name.clone(),
            element,
            reason,
        };
        let mut mapped: Vec<Option<usize>> = vec![None; rig.body_count()];
        let mut pairs = Vec::with_capacity(map.pairs.len());
        for (k, (joint, body)) in map.pairs.iter().enumerate() {
            let j = character.joint(joint).ok_or_else(|| {
                invalid(
                    format!("rig map pair {k}"),
                    format!("joint '{joint}' is not in the character"),
                )
            })?;
            let b = rig.body_index(body).ok_or_else(|| {
                invalid(
                    format!("rig map pair {k}"),
                    format!("body '{body}' is not in the anatomy (joint '{joint}' has no match)"),
                )
            })?;
            mapped[b] = Some(j);
            pairs.push((j, b));
        }
        let origin = |b: usize| Vec3::from(rest[b].translation);
        let mapped_ancestor = |b: usize| {
            let mut at = rig.parent(b);
            while let Some(p) = at {
                if mapped[p].is_some() {
                    return Some(p);
                }
                at = rig.parent(p);
            }
            None
        };
        // The character's size relative to the anatomy's: the RMS spread of
        // every mapped joint about their centre over the bodies'.
        let overall = {
            let (from, to): (Vec<Vec3>, Vec<Vec3>) = pairs
                .iter()
                .map(|&(j, b)| (origin(b), character.joints[j].origin))
                .unzip();
            let n = from.len().max(1) as f32;
            let (a_mean, c_mean) = (from.iter().sum::<Vec3>() / n, to.iter().sum::<Vec3>() / n);
            let spread = |points: &[Vec3], mean: Vec3| -> f32 {
                points.iter().map(|p| (*p - mean).length_squared()).sum()
            };
            let (a, c) = (spread(&from, a_mean), spread(&to, c_mean));
            if a > 0.0 { (c / a).sqrt() } else { 1.0 }
        };
        let mut fits: Vec<Option<Similarity>> = vec![None; rig.body_count()];
        let mut segments = Vec::with_capacity(pairs.len());
        // Parents come before children in a rig, so a leaf's parent segment
        // is fitted first when bodies are visited in order.
        let mut by_body: Vec<(usize, usize)> = pairs.iter().map(|&(j, b)| (b, j)).collect();
        by_body.sort_unstable();
        for &(b, j) in &by_body {
            let children: Vec<usize> = (0..rig.body_count())
                .filter(|&c| mapped[c].is_some() && mapped_ancestor(c) == Some(b))
                .collect();
            let (a, c) = (origin(b), character.joints[j].origin);
            let similarity = if children.is_empty() {
                let parent = mapped_ancestor(b).and_then(|p| fits[p]);
                let parent = parent.unwrap_or(Similarity::IDENTITY);
                Similarity {
                    translation: c - parent.scale * (parent.rotation * a),
                    ..parent
                }
            } else {
                let free = map.free.iter().any(|f| f == &rig.body_names()[b]);
                let (mut from, mut to) = if free {
                    (vec![], vec![])
                } else {
                    (vec![a], vec![c])
                };
                for &k in &children {
                    from.push(origin(k));
                    to.push(character.joints[mapped[k].expect("mapped")].origin);
                }
                let fitted = if free {
                    least_squares_similarity(&from, &to).map(|f| {
                        // The free body's own size is not measurable from
                        // the rig: the character's overall scale.
                        let rotation = f.rotation;
                        let n = from.len() as f32;
                        let (a_mean, c_mean) =
                            (from.iter().sum::<Vec3>() / n, to.iter().sum::<Vec3>() / n);
                        Similarity {
                            scale: overall,
                            rotation,
                            translation: c_mean - overall * (rotation * a_mean),
                        }
                    })
                } else {
                    least_squares_similarity(&from, &to)
                };
                fitted.ok_or_else(|| {
                    invalid(
                        format!(
                            "segment {} / {}",
                            character.joints[j].name,
                            rig.body_names()[b]
                        ),
                        "its children are at its own origin: no direction to fit".into(),
                    )
                })?
            };
            let fitted = !children.is_empty();
            let end = if fitted {
                children.iter().map(|&k| origin(k)).sum::<Vec3>() / children.len() as f32
            } else {
                a
            };
            fits[b] = Some(similarity);
            segments.push((
                j,
                SegmentFit {
                    joint: character.joints[j].name.clone(),
                    body: rig.body_names()[b].clone(),
                    similarity,
                    fitted_to_children: fitted,
                    line: (a, end),
                },
            ));
        }
        // The map's order for the report.
        let segments: Vec<SegmentFit> = map
            .pairs
            .iter()
            .filter_map(|(joint, _)| segments.iter().find(|(_, s)| &s.joint == joint))
            .map(|(_, s)| s.clone())
            .collect();
        let mut bodies = Vec::with_capacity(rig.body_count());
        for b in 0..rig.body_count() {
            let own = fits[b]
                .or_else(|| mapped_ancestor(b).and_then(|p| fits[p]))
                .or_else(|| {
                    (b..rig.body_count())
                        .find(|&d| fits[d].is_some() && descends(rig, d, b))
                        .and_then(|d| fits[d])
                });
            bodies.push(
                own.or(fits.iter().flatten().next().copied())
                    .unwrap_or(Similarity::IDENTITY),
            );
        }
        let parents: Vec<Option<usize>> = (0..rig.body_count()).map(|b| rig.parent(b)).collect();
        let segment_index = |b: usize| {
            let body = &rig.body_names()[b];
            segments.iter().position(|s: &SegmentFit| &s.body == body)
        };
        let segment_of = (0..rig.body_count())
            .map(|b| {
                if mapped[b].is_some() {
                    return segment_index(b);
                }
                mapped_ancestor(b).and_then(segment_index).or_else(|| {
                    (b..rig.body_count())
                        .find(|&d| mapped[d].is_some() && descends(rig, d, b))
                        .and_then(segment_index)
                })
            })
            .collect();
        Ok(Self {
            bodies,
            segments,
            parents,
            segment_of,
        })
    }
}

/// The similarity that maps `from` onto `to` best in the least-squares
/// sense (Horn's quaternion method; two points: the shortest turn between
/// them, which leaves the roll about their line alone). `None` when the
/// points of `from` coincide.
pub fn least_squares_similarity(from: &[Vec3], to: &[Vec3]) -> Option<Similarity> {
    let n = from.len() as f32;
    let (a_mean, c_mean) = (from.iter().sum::<Vec3>() / n, to.iter().sum::<Vec3>() / n);
    let a: Vec<Vec3> = from.iter().map(|&p| p - a_mean).collect();
    let c: Vec<Vec3> = to.iter().map(|&p| p - c_mean).collect();
    let spread: f32 = a.iter().map(|p| p.length_squared()).sum();
    if spread < 1e-12 {
        return None;
    }
    let rotation = if from.len() == 2 {
        let (u, v) = (a[1] - a[0], c[1] - c[0]);
        if v.length() < 1e-9 {
            Quat::IDENTITY
        } else {
            Quat::from_rotation_arc(u.normalize(), v.normalize())
        }
    } else {
        horn_rotation(&a, &c)
    };
    let scale = a
        .iter()
        .zip(&c)
        .map(|(&p, &q)| q.dot(rotation * p))
        .sum::<f32>()
        / spread;
    Some(Similarity {
        scale,
        rotation,
        translation: c_mean - scale * (rotation * a_mean),
    })
}

/// The rotation that best turns the centred points `a` onto `c`: the
/// eigenvector of the largest eigenvalue of Horn's 4 × 4 matrix.
fn horn_rotation(a: &[Vec3], c: &[Vec3]) -> Quat {
    let mut s = [[0.0f64; 3]; 3];
    for (p, q) in a.iter().zip(c) {
        for (i, pi) in p.to_array().into_iter().enumerate() {
            for (j, qj) in q.to_array().into_iter().enumerate() {
                s[i][j] += pi as f64 * qj as f64;
            }
        }
    }
    let [[xx, xy, xz], [yx, yy, yz], [zx, zy, zz]] = s;
    let mut m = [
        [xx + yy + zz, yz - zy, zx - xz, xy - yx],
        [yz - zy, xx - yy - zz, xy + yx, zx + xz],
        [zx - xz, xy + yx, -xx + yy - zz, yz + zy],
        [xy - yx, zx + xz, yz + zy, -xx - yy + zz],
    ];
    // Cyclic Jacobi sweeps: m → diagonal, v → eigenvectors (columns).
    let mut v = [[0.0f64; 4]; 4];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for _ in 0..32 {
        let off: f64 = (0..4)
            .flat_map(|i| (0..4).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| m[i][j] * m[i][j])
            .sum();
        if off < 1e-24 {
            break;
        }
        for p in 0..4 {
            for q in p + 1..4 {
                if m[p][q].abs() < 1e-30 {
                    continue;
                }
                let theta = (m[q][q] - m[p][p]) / (2.0 * m[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let (cos, sin) = (1.0 / (t * t + 1.0).sqrt(), t / (t * t + 1.0).sqrt());
                for row in &mut m {
                    let (mkp, mkq) = (row[p], row[q]);
                    row[p] = cos * mkp - sin * mkq;
                    row[q] = sin * mkp + cos * mkq;
                }
                let (row_p, row_q) = (m[p], m[q]);
                for k in 0..4 {
                    m[p][k] = cos * row_p[k] - sin * row_q[k];
                    m[q][k] = sin * row_p[k] + cos * row_q[k];
                }
                for row in &mut v {
                    let (vp, vq) = (row[p], row[q]);
                    row[p] = cos * vp - sin * vq;
                    row[q] = sin * vp + cos * vq;
                }
            }
        }
    }
    let best = (0..4)
        .max_by(|&i, &j| m[i][i].total_cmp(&m[j][j]))
        .unwrap_or(0);
    let (w, x, y, z) = (v[0][best], v[1][best], v[2][best], v[3][best]);
    Quat::from_xyzw(x as f32, y as f32, z as f32, w as f32).normalize()
}

/// Whether body `d` is `ancestor` or below it.
fn descends(rig: &SkeletonRig, d: usize, ancestor: usize) -> bool {
    let mut at = Some(d);
    while let Some(b) = at {
        if b == ancestor {
            return true;
        }
        at = rig.parent(b);
    }
    false
}

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
        let bones = solver
            .bones()
            .iter()
            .filter_map(|bone| {
                let target = &solver.targets()[bone.target?];
                let fit = bone
                    .body
                    .and_then(|body| self.bodies.get(body))
                    .copied()
                    .unwrap_or(Similarity::IDENTITY);
                let world = target
                    .positions
                    .iter()
                    .map(|&p| fit.apply(bone.transform.transform_point3(p) / unit))
                    .collect();
                Some(world)
            })
            .zip(
                solver
                    .bones()
                    .iter()
                    .enumerate()
                    .filter(|(_, b)| b.target.is_some()),
            )
            .map(|(world, (b, _))| (b, world))
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

/// The volume inside a character's skin at its bind pose, for inside and
/// outside tests (the side of the closest skin point's normal; holes such
/// as the eyes' and mouth's are tolerated).
#[derive(Clone, Debug)]
pub struct SkinVolume {
    surface: TargetSurface,
}

impl SkinVolume {
    /// The skin of `character` at its bind pose.
    pub fn new(character: &SkinnedCharacter) -> Self {
        let mut surface = TargetSurface::new(
            format!("{} skin", character.name),
            TargetSource::Bone(0),
            character.positions.clone(),
            character.triangles.clone(),
        );
        surface.set_transform(Affine3A::IDENTITY);
        Self { surface }
    }

    /// How far `p` is outside the skin (m; ≤ 0 inside).
    pub fn outside_by(&self, p: Vec3) -> f32 {
        self.surface
            .closest_within(p, None, f32::MAX)
            .map_or(f32::INFINITY, |hit| hit.signed_distance)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn least_squares_recovers_a_similarity() {
        let truth = Similarity {
            scale: 1.3,
            rotation: Quat::from_axis_angle(Vec3::new(1.0, 2.0, -0.5).normalize(), 0.9),
            translation: Vec3::new(0.1, -0.4, 0.25),
        };
        let from = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.3, 0.1, 0.0),
            Vec3::new(-0.1, 0.4, 0.2),
            Vec3::new(0.2, -0.2, 0.5),
        ];
        let to: Vec<Vec3> = from.iter().map(|&p| truth.apply(p)).collect();
        let fit = least_squares_similarity(&from, &to).unwrap();
        assert!((fit.scale - truth.scale).abs() < 1e-4, "{fit:?}");
        assert!(fit.rotation.angle_between(truth.rotation) < 1e-3, "{fit:?}");
        assert!(
            fit.translation.distance(truth.translation) < 1e-4,
            "{fit:?}"
        );
        // Two points: exact ends, shortest turn.
        let fit = least_squares_similarity(&from[..2], &to[..2]).unwrap();
        for (p, q) in from[..2].iter().zip(&to[..2]) {
            assert!(fit.apply(*p).distance(*q) < 1e-5);
        }
        assert!(least_squares_similarity(&[Vec3::ONE; 3], &to[..3]).is_none());
    }
}
