//! Skin binding: a body's surface vertices held, softly, to where
//! linear-blend skinning puts them — the connection that makes a character's
//! skin follow its skeleton while the muscles below push it out.
//!
//! Each bound vertex has up to [`MAX_BONES`] bones and weights (a glTF
//! skin's `JOINTS_0`/`WEIGHTS_0`); its goal is `Σ w_k M_k(t) ℓ_k`, with `ℓ_k`
//! the vertex's rest position in bone `k`'s frame at build time and `M_k(t)`
//! the bone's pose (the same sum glTF's skinning computes). A
//! [`ConstraintKind::Bind`](super::ConstraintKind::Bind) constraint pulls
//! the vertex towards it with compliance
//! [`Compliances::bind`](super::Compliances::bind) ÷ the vertex's strength.

use super::{LinePose, LineShape, Muscle};
use crate::closest::TargetSurface;
use crate::constraints::{ParticleId, PointBatch};
use crate::error::BuildError;
use glam::{Affine3A, Vec3};

/// Most bones one vertex is bound to (glTF's four joints per vertex).
pub const MAX_BONES: usize = 4;

/// How a body's surface is bound to bones, per surface vertex.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SkinBindingDesc {
    /// Per surface vertex: `(bone index in the solver, weight)` pairs, at
    /// most [`MAX_BONES`], weights ≥ 0 summing to 1; an empty list leaves
    /// the vertex unbound.
    pub influences: Vec<Vec<(usize, f32)>>,
    /// Per surface vertex, the binding's strength (the weight map: the
    /// compliance is divided by it; 0 unbinds the vertex). Empty: 1 for
    /// every vertex. Unitless, ≥ 0.
    pub strength: Vec<f32>,
    /// Made by [`SkinBindingDesc::holding_shape`]: a muscle's held shape
    /// ([`super::MuscleParams::hold_shape`]), which
    /// [`super::MuscleParams::hold_frame`] may carry along the muscle's
    /// line of action instead of these bones. `false` for a skin's
    /// weights.
    pub holds_shape: bool,
}

/// One bound vertex, resolved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundVertex {
    /// The surface vertex.
    pub vertex: ParticleId,
    /// Bones (unused slots have weight 0).
    pub bones: [u32; MAX_BONES],
    /// Weights, summing to 1.
    pub weights: [f32; MAX_BONES],
    /// The vertex's rest position in each bone's frame.
    pub local: [Vec3; MAX_BONES],
    /// Strength (the compliance is divided by it).
    pub strength: f32,
}

impl BoundVertex {
    /// The skinned goal for bone poses `pose`.
    #[inline]
    pub fn goal(&self, pose: &impl Fn(usize) -> Affine3A) -> Vec3 {
        let mut goal = Vec3::ZERO;
        for k in 0..MAX_BONES {
            if self.weights[k] > 0.0 {
                goal +=
                    self.weights[k] * pose(self.bones[k] as usize).transform_point3(self.local[k]);
            }
        }
        goal
    }
}

impl SkinBindingDesc {
    /// The binding [`super::MuscleParams::hold_shape`] gives a muscle with
    /// surface `positions` (rest, world) and held vertices `held` (`(bone,
    /// vertex)`, `None` for a world point): every vertex bound to the bones
    /// around it — those it is attached to and the bones in `surfaces`
    /// (bone index and its surface, posed as at rest) — weighted by the
    /// inverse square of its distance to each (to the bone's surface, or to
    /// its nearest held vertex on that bone, whichever is nearer), the
    /// [`MAX_BONES`] largest kept. A forearm muscle attached to the humerus
    /// and the hand follows the radius and the ulna it lies on, not a blend
    /// of the two ends (which would cut across a bent elbow). `None` when
    /// there is no bone.
    pub fn holding_shape(
        positions: &[Vec3],
        held: &[(Option<usize>, u32)],
        surfaces: &[(usize, &TargetSurface)],
    ) -> Option<Self> {
        let mut bones: Vec<usize> = held
            .iter()
            .filter_map(|&(b, _)| b)
            .chain(surfaces.iter().map(|&(b, _)| b))
            .collect();
        bones.sort_unstable();
        bones.dedup();
        if bones.is_empty() {
            return None;
        }
        let influences = positions
            .iter()
            .map(|&x| {
                let mut weights: Vec<(usize, f32)> = bones
                    .iter()
                    .map(|&bone| {
                        let to_held = held
                            .iter()
                            .filter(|&&(b, _)| b == Some(bone))
                            .map(|&(_, v)| positions[v as usize].distance(x))
                            .fold(f32::INFINITY, f32::min);
                        let to_surface = surfaces
                            .iter()
                            .filter(|&&(b, _)| b == bone)
                            .filter_map(|(_, t)| t.closest(x, None))
                            .map(|hit| Vec3::from(hit.point).distance(x))
                            .fold(f32::INFINITY, f32::min);
                        let d = to_held.min(to_surface);
                        (bone, 1.0 / (d * d).max(f32::MIN_POSITIVE.sqrt()))
                    })
                    .collect();
                weights.sort_by(|a, b| b.1.total_cmp(&a.1));
                weights.truncate(MAX_BONES);
                let sum: f32 = weights.iter().map(|w| w.1).sum();
                weights.iter().map(|&(b, w)| (b, w / sum)).collect()
            })
            .collect();
        Some(Self {
            influences,
            strength: Vec::new(),
            holds_shape: true,
        })
    }

    /// Checks the desc against a surface at the rest `positions` (one list
    /// and strength per vertex, weights ≥ 0 summing to 1, strengths finite
    /// and ≥ 0) and resolves it with the bones at `bone_transform`, which
    /// must know every bone named (the solver checks them first, beside the
    /// attachments' bones). `muscle` names it in errors.
    pub fn resolve(
        &self,
        muscle: &str,
        positions: &[Vec3],
        bone_transform: &impl Fn(usize) -> Affine3A,
    ) -> Result<Vec<BoundVertex>, BuildError> {
        let bad = |parameter: String, value: f32, reason: String| BuildError::InvalidParameter {
            muscle: muscle.to_string(),
            parameter,
            value,
            reason,
        };
        let n = positions.len();
        if self.influences.len() != n {
            return Err(bad(
                "binding.influences".into(),
                self.influences.len() as f32,
                format!("one list per surface vertex: the surface has {n}"),
            ));
        }
        if !self.strength.is_empty() && self.strength.len() != n {
            return Err(bad(
                "binding.strength".into(),
                self.strength.len() as f32,
                format!("empty or one value per surface vertex: the surface has {n}"),
            ));
        }
        let mut bound = Vec::new();
        for (v, influences) in self.influences.iter().enumerate() {
            let strength = self.strength.get(v).copied().unwrap_or(1.0);
            if !(strength.is_finite() && strength >= 0.0) {
                return Err(bad(
                    format!("binding.strength[{v}]"),
                    strength,
                    "must be finite and ≥ 0".into(),
                ));
            }
            if influences.is_empty() || strength == 0.0 {
                continue;
            }
            if influences.len() > MAX_BONES {
                return Err(bad(
                    format!("binding.influences[{v}]"),
                    influences.len() as f32,
                    format!("at most {MAX_BONES} bones per vertex"),
                ));
            }
            let sum: f32 = influences.iter().map(|&(_, w)| w).sum();
            if influences
                .iter()
                .any(|&(_, w)| !(w.is_finite() && w >= 0.0))
                || (sum - 1.0).abs() > 1e-3
            {
                return Err(bad(
                    format!("binding.influences[{v}]"),
                    sum,
                    format!("weights {influences:?} must be ≥ 0 and sum to 1"),
                ));
            }
            let mut vertex = BoundVertex {
                vertex: ParticleId::new(v as u32),
                bones: [0; MAX_BONES],
                weights: [0.0; MAX_BONES],
                local: [Vec3::ZERO; MAX_BONES],
                strength,
            };
            for (k, &(bone, weight)) in influences.iter().enumerate() {
                vertex.bones[k] = bone as u32;
                vertex.weights[k] = weight / sum;
                vertex.local[k] = bone_transform(bone)
                    .inverse()
                    .transform_point3(positions[v]);
            }
            bound.push(vertex);
        }
        Ok(bound)
    }
}

/// The Bind constraints of `m`: one per bound vertex, towards its skinned
/// goal (at rest: where it is), compliance ÷ strength.
pub fn bind_constraints(m: &Muscle) -> PointBatch {
    let mut batch = PointBatch::default();
    for b in &m.binding {
        let i = b.vertex.index();
        batch.push(b.vertex, m.x[i], 0.0, m.bind_compliance(b.strength));
    }
    batch
}

/// Refreshes the Bind goals for bone poses `pose` (before each substep's
/// projection, with the attachments'): skinned, or along the muscle's line
/// of action where its held shape follows one ([`Muscle::hold_line`]).
pub fn update_bind_goals(m: &mut Muscle, pose: &impl Fn(usize) -> Affine3A) {
    let shape = LineShape::of(&m.params);
    let line = m.hold_line.as_mut().map(|line| line.pose_kept(pose, shape));
    update_bind_goals_in(m, pose, line.as_ref());
}

/// [`update_bind_goals`] with the hold line's pose already taken (`line`,
/// by [`crate::muscle::HoldLine::pose_kept`]; `None` for a muscle without
/// one).
pub(crate) fn update_bind_goals_in(
    m: &mut Muscle,
    pose: &impl Fn(usize) -> Affine3A,
    line: Option<&LinePose>,
) {
    if line.is_some() && m.hold_line.is_some() && m.params.rest_follows_hold {
        m.follow_held_shape();
        return;
    }
    let goals = m.constraints.bind.goal.iter_mut().zip(&m.binding);
    match m.hold_line.as_ref().zip(line) {
        Some((line, now)) => {
            for (goal, b) in goals {
                *goal = line.goal(now, b.vertex.index());
            }
            m.release_held_rest();
        }
        None => {
            for (goal, b) in goals {
                *goal = b.goal(pose);
            }
        }
    }
}
