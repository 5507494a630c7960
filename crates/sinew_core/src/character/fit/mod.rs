//! Fitting an anatomy (a scene's skeleton, bones and muscles) to a
//! character: a [`RigMap`] pairs the character's joints with the anatomy's
//! bodies, and each anatomical segment gets a similarity (uniform scale,
//! rotation, translation) that puts its body's origin on the paired joint
//! and its mapped children's origins in the direction, and at the distance,
//! of their joints ([`AnatomyFit::new`]).
//!
//! Both sides are in the same frame: metres, +Y up, facing +Z (glTF's, and
//! the imported anatomy's).

mod geometry;
mod inside;
mod pipeline;
mod scene;
mod similarity;
mod skin;
mod spread;

pub use geometry::{FittedGeometry, SkinVolume};
pub use inside::{PullInside, PullReport};
pub use pipeline::{FitOptions, FittedAnatomy, fit_anatomy};
pub use scene::{FittedScene, HELD_UNDER_SKIN};
pub use similarity::least_squares_similarity;
pub use skin::SkinLayer;

use super::{CharacterError, SkinnedCharacter};
use crate::skeleton::SkeletonRig;
use glam::{Affine3A, Quat, Vec3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The smallest segment scale (character length / anatomy length) a fit
/// accepts: below it the character's joints of the segment coincide.
const MIN_SCALE: f32 = 1e-3;

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
        // A game rig's spine, neck and head joints run through the middle of
        // the trunk and neck, the vertebrae behind them: the pelvis is fitted
        // to the hips and the chest (`spine_03`) to the thorax as a whole
        // (clavicles and head), their own origins free, and these and the
        // head are settled in the skin front to back
        // ([`AnatomyFit::settle_in_skin`]); the lumbar vertebrae go with the
        // chest.
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
            ("thumb_01", "firstmc"),
            ("thumb_02", "proximal_thumb"),
            ("thumb_03", "distal_thumb"),
            ("index_01", "2proxph"),
            ("index_02", "midph2"),
            ("index_03", "distph2"),
            ("middle_01", "3proxph"),
            ("middle_02", "midph3"),
            ("middle_03", "distph3"),
            ("ring_01", "4proxph"),
            ("ring_02", "midph4"),
            ("ring_03", "distph4"),
            ("pinky_01", "5proxph"),
            ("pinky_02", "midph5"),
            ("pinky_03", "distph5"),
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
            free: vec!["pelvis".into(), "torso".into(), "head".into()],
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
            reason: crate::ron_text::describe(&e.code),
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

/// A similarity for every body of an anatomy ([`AnatomyFit::body`]).
#[derive(Clone, Debug, PartialEq)]
pub struct AnatomyFit {
    /// The mapped segments, in the map's order.
    pub segments: Vec<SegmentFit>,
    /// Per rig body, its parent.
    parents: Vec<Option<usize>>,
    /// Per rig body, the segment (index in `segments`) whose similarity it
    /// takes.
    segment_of: Vec<Option<usize>>,
}

impl AnatomyFit {
    /// The similarity of rig body `b`: its segment's (its own when mapped,
    /// else its nearest mapped ancestor's, else the nearest mapped body's);
    /// the identity when nothing is mapped.
    pub fn body(&self, b: usize) -> Similarity {
        self.segment_of
            .get(b)
            .copied()
            .flatten()
            .map_or(Similarity::IDENTITY, |k| self.segments[k].similarity)
    }

    /// Fits `rig` (its bodies' world frames at rest: `rest`) to
    /// `character` through `map`. A mapped body's similarity puts its
    /// origin on its joint and turns and scales the segment to its nearest
    /// mapped descendants (their centroid); a mapped leaf keeps its parent
    /// segment's rotation and scale; an unmapped body takes its nearest
    /// mapped ancestor's similarity, or, with no mapped ancestor, that of the
    /// mapped body whose origin is nearest to its own. Errors name a joint the character lacks or a body
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
        // The character's size relative to the anatomy's: the height (Y
        // extent) of the mapped joints over that of the bodies' origins —
        // heights do not change between an A-pose and arms hanging.
        let overall = {
            let extent = |ys: &mut dyn Iterator<Item = f32>| {
                let (lo, hi) = ys.fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), y| {
                    (lo.min(y), hi.max(y))
                });
                hi - lo
            };
            let anatomy = extent(&mut pairs.iter().map(|&(_, b)| origin(b).y));
            let body = extent(&mut pairs.iter().map(|&(j, _)| character.joints[j].origin.y));
            if anatomy > 0.0 { body / anatomy } else { 1.0 }
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
                let segment = || {
                    format!(
                        "segment {} / {}",
                        character.joints[j].name,
                        rig.body_names()[b]
                    )
                };
                let fitted = fitted.ok_or_else(|| {
                    invalid(
                        segment(),
                        "its children are at its own origin: no direction to fit".into(),
                    )
                })?;
                // The character's joints of the segment on top of each
                // other: a scale of (almost) zero would crush its bones.
                if !(fitted.scale.is_finite() && fitted.scale > MIN_SCALE) {
                    return Err(invalid(
                        segment(),
                        format!(
                            "the character's joints of this segment coincide (scale {}): no direction to fit",
                            fitted.scale
                        ),
                    ));
                }
                fitted
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
        // A body with no mapped ancestor (the trunk's roots beside the
        // pelvis) goes with the mapped body whose origin is nearest to its own.
        let nearest_mapped = |b: usize| {
            (0..rig.body_count())
                .filter(|&d| mapped[d].is_some())
                .min_by(|&x, &y| {
                    let distance = |d: usize| origin(d).distance(origin(b));
                    distance(x).total_cmp(&distance(y))
                })
        };
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
                mapped_ancestor(b)
                    .or_else(|| nearest_mapped(b))
                    .and_then(segment_index)
            })
            .collect();
        Ok(Self {
            segments,
            parents,
            segment_of,
        })
    }
}
