//! What a muscle is built from: its description ([`MuscleDesc`]) — mesh,
//! roots, attachments, targets, parameters and per-vertex maps.

use super::{MuscleParams, SkinBindingDesc, nearest_vertex};
use crate::error::BuildError;
use crate::mesh::SurfaceMesh;
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Which surface vertices seed the internal structure.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub enum Roots {
    /// Explicit vertex indices.
    Vertices(Vec<u32>),
    /// The vertices used by the muscle's attachments (tendon ends).
    #[default]
    Attachments,
    /// The two vertices at the extremes of the mesh's principal axis.
    LongestAxisTips,
}

/// Where a muscle is held.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AttachmentDesc {
    /// Bone index in the solver, or `None` for a fixed world point.
    pub bone: Option<usize>,
    /// The held vertex; `None` picks the vertex nearest `point`.
    pub vertex: Option<u32>,
    /// Rest-pose world point used when `vertex` is `None`.
    pub point: Option<Vec3>,
    /// With `point`: hold every surface vertex within this distance of it
    /// (a region, e.g. a tendon's end), at least the nearest. `0`: the
    /// nearest vertex only. Units: scene units. Default: `0`.
    pub radius: f32,
}

/// A held vertex and its bone (`None`: a world point).
type HeldVertex = (Option<usize>, u32);

/// What `attachments` hold on a mesh with vertex `positions`: each
/// attachment's root, in order, and every held vertex with its bone
/// (`None`: a world point), attachment by attachment
/// ([`AttachmentDesc::for_each_held_vertex`]). `muscle` names it in errors.
pub(crate) fn held_by(
    attachments: &[AttachmentDesc],
    positions: &[Vec3],
    muscle: &str,
) -> Result<(Vec<u32>, Vec<HeldVertex>), BuildError> {
    let mut roots = Vec::with_capacity(attachments.len());
    let mut held = Vec::with_capacity(attachments.len());
    for (i, a) in attachments.iter().enumerate() {
        roots.push(a.for_each_held_vertex(positions, muscle, i, |v| held.push((a.bone, v)))?);
    }
    Ok((roots, held))
}

impl AttachmentDesc {
    /// The surface vertices this attachment holds on a mesh with vertex
    /// `positions`, its root (the given vertex, or the one nearest `point`)
    /// first, then the rest of its region. `muscle` and `index` (its place
    /// in the muscle's list) name it in errors: a vertex out of range, a
    /// radius that is negative or not finite, neither vertex nor point.
    pub fn held_vertices(
        &self,
        positions: &[Vec3],
        muscle: &str,
        index: usize,
    ) -> Result<Vec<u32>, BuildError> {
        let mut held = Vec::new();
        self.for_each_held_vertex(positions, muscle, index, |v| held.push(v))?;
        Ok(held)
    }

    /// [`AttachmentDesc::held_vertices`] without a list: calls `hold` with
    /// each held vertex in the same order and returns the root. (The build
    /// uses it: an allocation per attachment moves every muscle's arrays in
    /// memory, and the projection's speed depends on where they land —
    /// 28 % on T5 when they moved.)
    pub fn for_each_held_vertex(
        &self,
        positions: &[Vec3],
        muscle: &str,
        index: usize,
        mut hold: impl FnMut(u32),
    ) -> Result<u32, BuildError> {
        let n = positions.len();
        if !(self.radius >= 0.0 && self.radius.is_finite()) {
            return Err(BuildError::InvalidParameter {
                muscle: muscle.into(),
                parameter: format!("attachments[{index}].radius"),
                value: self.radius,
                reason: "must be finite and ≥ 0".into(),
            });
        }
        let root = match (self.vertex, self.point) {
            (Some(v), _) => v,
            (None, Some(point)) if point.is_finite() => nearest_vertex(positions, point),
            (None, _) => {
                return Err(BuildError::InvalidParameter {
                    muscle: muscle.into(),
                    parameter: format!("attachments[{index}]"),
                    value: f32::NAN,
                    reason: "an attachment needs a vertex or a finite point".into(),
                });
            }
        };
        if root as usize >= n {
            return Err(BuildError::AttachmentVertexOutOfRange {
                muscle: muscle.into(),
                attachment: index,
                vertex: root,
                count: n,
            });
        }
        hold(root);
        if let (None, Some(point), true) = (self.vertex, self.point, self.radius > 0.0) {
            let r2 = self.radius * self.radius;
            (0..n as u32)
                .filter(|&u| u != root && positions[u as usize].distance_squared(point) <= r2)
                .for_each(hold);
        }
        Ok(root)
    }
}

/// A target of a muscle: a bone with a mesh, or another muscle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TargetRef {
    /// Bone index in the solver.
    Bone(usize),
    /// Muscle index in the solver.
    Muscle(usize),
}

/// Optional per-vertex maps (one value per surface vertex).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VertexMaps {
    /// Sliding weight per vertex (replaces `weights.sliding`).
    pub sliding: Option<Vec<f32>>,
    /// Soft weight per vertex.
    pub soft: Option<Vec<f32>>,
    /// Hard weight per vertex.
    pub hard: Option<Vec<f32>>,
    /// Combed fibre per vertex; a zero vector keeps the computed fibre.
    pub fibers: Option<Vec<Vec3>>,
    /// Mass multiplier per vertex.
    pub mass: Option<Vec<f32>>,
    /// Tendon mask per vertex, in `[0, 1]`: 1 is tendon, which neither
    /// shortens nor bulges with activation; 0 is contractile belly; between,
    /// in proportion. An edge takes the mean of its two ends (an internal
    /// point counts as belly). Default: none (all belly).
    pub tendon: Option<Vec<f32>>,
    /// Damping multiplier per vertex (`≥ 0`) of the muscle's damping rate
    /// [`MuscleParams::damping`] (1/s): 0 undamped, 2 twice as damped.
    /// Internal points keep the muscle's rate. Default: none (1 everywhere).
    pub damping: Option<Vec<f32>>,
    /// Thickness per vertex of what lies under it (a skin's fat): how
    /// close the vertex may come to the muscles and bones it slides on.
    /// Its rest gap to each is the smaller of this and its distance at rest
    /// — fat thinner than the skin's rest distance lets the skin be pressed
    /// in down to it (in [`crate::constraints::SlidingMode::Contact`]; a
    /// [`crate::constraints::SlidingMode::KeepGap`] vertex is drawn to
    /// it). Units: scene units, `≥ 0`. Default: none (the distance at rest
    /// everywhere).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub thickness: Option<Vec<f32>>,
}

impl VertexMaps {
    /// These maps, each one missing here taken from `other` (a map given
    /// here wins).
    pub fn or(self, other: VertexMaps) -> VertexMaps {
        let VertexMaps {
            sliding,
            soft,
            hard,
            fibers,
            mass,
            tendon,
            damping,
            thickness,
        } = other;
        VertexMaps {
            sliding: self.sliding.or(sliding),
            soft: self.soft.or(soft),
            hard: self.hard.or(hard),
            fibers: self.fibers.or(fibers),
            mass: self.mass.or(mass),
            tendon: self.tendon.or(tendon),
            damping: self.damping.or(damping),
            thickness: self.thickness.or(thickness),
        }
    }

    /// Checks every value: weights finite and ≥ 0, mass multipliers
    /// finite and > 0, thicknesses finite and ≥ 0, fibres finite. `muscle` names the muscle in the
    /// error, which names the map and the vertex.
    pub fn validate(&self, muscle: &str) -> Result<(), BuildError> {
        let bad = |map: &str, vertex: usize, value: f32, reason: &str| BuildError::MapValue {
            muscle: muscle.into(),
            map: map.into(),
            vertex,
            value,
            reason: reason.into(),
        };
        let weights = [
            ("sliding", &self.sliding),
            ("soft", &self.soft),
            ("hard", &self.hard),
        ];
        for (map, values) in weights {
            let values = values.iter().flatten().enumerate();
            if let Some((v, &w)) = values.clone().find(|(_, w)| !(w.is_finite() && **w >= 0.0)) {
                return Err(bad(map, v, w, "a weight must be finite and ≥ 0"));
            }
        }
        let mut masses = self.mass.iter().flatten().enumerate();
        if let Some((v, &m)) = masses.find(|(_, m)| !(m.is_finite() && **m > 0.0)) {
            return Err(bad(
                "mass",
                v,
                m,
                "a mass multiplier must be finite and > 0",
            ));
        }
        let mut tendon = self.tendon.iter().flatten().enumerate();
        if let Some((v, &t)) = tendon.find(|(_, t)| !(0.0..=1.0).contains(*t)) {
            return Err(bad("tendon", v, t, "a tendon mask must be in [0, 1]"));
        }
        let mut damping = self.damping.iter().flatten().enumerate();
        if let Some((v, &d)) = damping.find(|(_, d)| !(d.is_finite() && **d >= 0.0)) {
            return Err(bad(
                "damping",
                v,
                d,
                "a damping multiplier must be finite and ≥ 0",
            ));
        }
        let mut thickness = self.thickness.iter().flatten().enumerate();
        if let Some((v, &t)) = thickness.find(|(_, t)| !(t.is_finite() && **t >= 0.0)) {
            return Err(bad("thickness", v, t, "a thickness must be finite and ≥ 0"));
        }
        let mut fibers = self.fibers.iter().flatten().enumerate();
        if let Some((v, f)) = fibers.find(|(_, f)| !f.is_finite()) {
            let value = f
                .to_array()
                .into_iter()
                .find(|c| !c.is_finite())
                .unwrap_or(f32::NAN);
            return Err(bad("fibers", v, value, "a fibre must be finite"));
        }
        Ok(())
    }
}

/// Everything needed to build one muscle.
#[derive(Clone, Debug)]
pub struct MuscleDesc {
    /// Unique name.
    pub name: String,
    /// Closed surface mesh in world space at the start frame.
    pub mesh: SurfaceMesh,
    /// Seeds of the internal structure.
    pub roots: Roots,
    /// Attachments.
    pub attachments: Vec<AttachmentDesc>,
    /// Targets (bones with meshes, other muscles).
    pub targets: Vec<TargetRef>,
    /// Parameters.
    pub params: MuscleParams,
    /// Per-vertex maps.
    pub maps: VertexMaps,
    /// Skin binding: surface vertices held softly to their linear-blend
    /// skinned positions (a character's skin layer). `None`: unbound.
    pub binding: Option<SkinBindingDesc>,
}
