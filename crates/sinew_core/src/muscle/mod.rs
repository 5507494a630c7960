//! A muscle — or any deformable body, such as a surface layer
//! ([`MuscleParams::surface_layer`]) — as plain data: particles, masses,
//! internal structure, fibres and constraints (SPEC §2, §5, §7), built by
//! [`Muscle::build`]. Target connections (Sliding, Soft, Hard) are linked by
//! the solver once every target exists; what the solver derives from a
//! muscle lives in its workspace, not here.

mod binding;
mod build;
mod constraints;
mod fiber;
mod internal;
mod mass;
mod params;

pub use binding::{BoundVertex, MAX_BONES, SkinBindingDesc, bind_constraints, update_bind_goals};
pub use build::{area_triangles, branch_links, fiber_edges, internal_links};
pub(crate) use constraints::{BATCHED_KINDS, MuscleLambdas};
pub use constraints::{Compliances, ConstraintCounts, ConstraintKind, MuscleConstraints};
pub use fiber::{fiber_field, longest_axis};
pub use internal::{InternalStructure, InternalStructureParams};
pub use params::{ConnectionWeights, MassMode, MuscleParams};

use crate::constraints::{ActivationScale, ParticleId, TargetSlot};
use crate::error::BuildError;
use crate::mesh::SurfaceMesh;
use glam::{Affine3A, Vec3};
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
#[serde(default)]
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

/// A resolved attachment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Attachment {
    /// Bone index, `None` for world.
    pub bone: Option<usize>,
    /// Held surface vertex.
    pub vertex: ParticleId,
    /// Held internal point, if the structure exists.
    pub internal_particle: Option<ParticleId>,
    /// Vertex rest position in the bone frame.
    pub vertex_local: Vec3,
    /// Internal point rest position in the bone frame.
    pub internal_local: Vec3,
}

/// Rest anchor of a Soft or Hard constraint on a target triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceAnchor {
    /// Target slot in the muscle's target list.
    pub target: TargetSlot,
    /// Triangle of the target.
    pub triangle: u32,
    /// Barycentric coordinates.
    pub barycentric: Vec3,
    /// Offset in the rest tangent frame (Hard only).
    pub local: Vec3,
    /// Whether the tie holds at all: its target is a bone, or a muscle
    /// within [`MuscleParams::contact_reach`]. A vertex with no such target
    /// keeps its Soft and Hard constraints, switched off.
    pub connected: bool,
}

/// A simulated muscle: particle state (surface vertices first, then internal
/// points), constraints and per-target closest data.
///
/// Particle arrays are SoA `Vec`s of `Vec3` (12 B) and `f32` (4 B): the hot
/// loops touch `p` and `w` only, so they stay dense.
#[derive(Clone, Debug)]
pub struct Muscle {
    /// Unique name.
    pub name: String,
    /// Parameters (activation etc. may change every frame).
    pub params: MuscleParams,
    /// Rest mesh (topology and start-frame positions).
    pub mesh: SurfaceMesh,
    /// Generated internal structure.
    pub structure: InternalStructure,
    /// Root vertices used.
    pub roots: Vec<u32>,
    /// Unit fibre per particle (vertices: surface field; internal points: tangent).
    pub fibers: Vec<Vec3>,
    /// Positions at the start of the frame.
    pub x: Vec<Vec3>,
    /// Predictions (XPBD working positions).
    pub p: Vec<Vec3>,
    /// Velocities. Units: m/s.
    pub v: Vec<Vec3>,
    /// Inverse masses. Units: 1/kg. Zero for particles held by an attachment
    /// of zero compliance: those follow their bone kinematically.
    pub w: Vec<f32>,
    /// Inverse masses before pinning (restored when an attachment's
    /// compliance becomes positive).
    pub free_w: Vec<f32>,
    /// Start-frame positions.
    pub rest: Vec<Vec3>,
    /// Number of surface vertices (particles `0..surface_count`).
    pub surface_count: usize,
    /// Resolved attachments.
    pub attachments: Vec<Attachment>,
    /// Surface vertices bound to bones by skinning weights (see
    /// [`SkinBindingDesc`]), one Bind constraint each.
    pub binding: Vec<BoundVertex>,
    /// Targets, in the order given.
    pub targets: Vec<TargetRef>,
    /// Constraint batches.
    pub constraints: MuscleConstraints,
    /// Per-vertex maps given at build time.
    pub maps: VertexMaps,
    /// Activation was outside [0, 1] and has been reported.
    pub activation_reported: bool,
    /// Scene units per metre the muscle was built in
    /// ([`crate::SolverSettings::length_unit`]): its SI parameters are
    /// converted by it.
    pub length_unit: f32,
    /// Bumped whenever the constraints are relinked, attached or switched
    /// on or off: what the solver derived from them (colour plans, Jacobi
    /// incidence, in its `MuscleWorkspace`) is stale once it differs.
    topology: u64,
}

impl Muscle {
    /// Whether this body is a skin: a surface layer
    /// ([`MuscleParams::is_surface_layer`]) bound to the skeleton. A muscle
    /// that holds its shape ([`MuscleParams::hold_shape`]) is bound too,
    /// but is no skin.
    pub fn is_skin(&self) -> bool {
        self.params.is_surface_layer() && !self.binding.is_empty()
    }

    /// [`MuscleParams::contact_reach`] in scene units.
    pub fn contact_reach(&self) -> f32 {
        self.params.contact_reach * self.length_unit
    }

    /// Area's compliance in scene units: [`Compliances::area`] (m³/N)
    /// times the square of the length unit, so that a skin in other units
    /// keeps its area as stiff.
    pub fn area_compliance(&self) -> f32 {
        self.params.compliance.area * self.length_unit.powi(2)
    }

    /// Volume's compliance in scene units: [`Compliances::volume`] (m³/N)
    /// times the length unit's fourth power, so that a scene in other
    /// units keeps its volume as stiff.
    pub fn volume_compliance(&self) -> f32 {
        self.params.compliance.volume * self.length_unit.powi(4)
    }

    /// The topology counter (see the field's docs).
    pub fn topology(&self) -> u64 {
        self.topology
    }

    /// Marks the constraints as changed: call it after editing a batch's
    /// particle indices or switching constraints on or off by hand (the
    /// methods of this type do it themselves).
    pub fn touch_topology(&mut self) {
        self.topology = self.topology.wrapping_add(1);
    }

    /// Adds one attachment (an Attach and, with an internal structure, a
    /// BranchAttach on the internal point nearest the vertex).
    pub fn add_attachment(
        &mut self,
        bone: Option<usize>,
        vertex: u32,
        bone_transform: impl Fn(usize) -> Affine3A,
    ) {
        let pose = bone.map(&bone_transform).unwrap_or(Affine3A::IDENTITY);
        let attachment = self.attachment_at(bone, vertex, pose);
        self.push_attachment(attachment);
        self.touch_topology();
    }

    /// The attachment that holds surface vertex `vertex` where it is now
    /// (its start-of-frame position `x`) to `bone` posed at `bone_pose`
    /// (world from bone; the identity for the world), with the internal
    /// point nearest it. Panics if `vertex` is not a surface vertex.
    pub fn attachment_at(
        &self,
        bone: Option<usize>,
        vertex: u32,
        bone_pose: Affine3A,
    ) -> Attachment {
        assert!(
            (vertex as usize) < self.surface_count,
            "attachment vertex {vertex} of muscle '{}' is not a surface vertex",
            self.name
        );
        let inv = bone_pose.inverse();
        let pv = self.x[vertex as usize];
        let internal_particle = (!self.structure.points.is_empty()).then(|| {
            let k = nearest_vertex(&self.structure.points, pv);
            ParticleId::new(self.surface_count as u32 + k)
        });
        let pi = internal_particle.map(|i| self.x[i.index()]).unwrap_or(pv);
        Attachment {
            bone,
            vertex: ParticleId::new(vertex),
            internal_particle,
            vertex_local: inv.transform_point3(pv),
            internal_local: inv.transform_point3(pi),
        }
    }

    /// Replaces every attachment with `attachments` (made by
    /// [`Muscle::attachment_at`] or kept from [`Muscle::attachments`]), in
    /// that order: particles no longer held get their masses back, the new
    /// ones are pinned as their compliance says. What a driver calls when
    /// a muscle is attached, detached or re-targeted at run time.
    pub fn set_attachments(&mut self, attachments: impl IntoIterator<Item = Attachment>) {
        for a in &self.attachments {
            let v = a.vertex.index();
            self.w[v] = self.free_w[v];
            if let Some(ip) = a.internal_particle {
                self.w[ip.index()] = self.free_w[ip.index()];
            }
        }
        self.attachments.clear();
        self.constraints.attach = Default::default();
        self.constraints.branch_attach = Default::default();
        for a in attachments {
            self.push_attachment(a);
        }
        self.pin_attachments();
        self.touch_topology();
    }

    /// Adds `a` and its constraints (goals where the particles are now).
    fn push_attachment(&mut self, a: Attachment) {
        let c = &mut self.constraints;
        let pv = self.x[a.vertex.index()];
        c.attach
            .push(a.vertex, pv, 0.0, self.params.compliance.attach);
        if let Some(ip) = a.internal_particle {
            let pi = self.x[ip.index()];
            c.branch_attach
                .push(ip, pi, 0.0, self.params.compliance.branch_attach);
        }
        self.attachments.push(a);
    }

    /// Applies the current activation: clamps it (reporting once), then updates
    /// fibre / branch / internal rest lengths and the volume ratio. Returns a
    /// warning when the activation had to be clamped for the first time.
    pub fn update_activation(&mut self) -> Option<String> {
        let raw = self.params.activation;
        let mut warning = None;
        if !(0.0..=1.0).contains(&raw) {
            if !self.activation_reported {
                warning = Some(format!(
                    "muscle '{}': activation {raw} outside [0, 1], clamped",
                    self.name
                ));
                self.activation_reported = true;
            }
            self.params.activation = if raw.is_nan() {
                0.0
            } else {
                raw.clamp(0.0, 1.0)
            };
        }
        let p = &self.params;
        let (a, a0) = (p.activation, p.rest_activation.min(0.95));
        let bulge = p.bulge.then(|| p.volume.activation_ratio(a, a0));
        let scale = ActivationScale::new(a, a0, p.max_contraction, bulge);
        let k = &mut self.constraints;
        k.fiber.update_rest(p.fiber_mode, &scale);
        k.branch.update_rest(p.fiber_mode, &scale);
        k.internal.update_rest(p.fiber_mode, &scale);
        if let Some(v) = &mut k.volume {
            v.ratio = p.volume.ratio(a, a0);
        }
        if self.holds_shape() {
            self.apply_bind_compliances();
        }
        warning
    }

    /// Whether this muscle's shape is held on its bones
    /// ([`MuscleParams::hold_shape`]): bound, and no skin.
    pub fn holds_shape(&self) -> bool {
        !self.binding.is_empty() && !self.params.is_surface_layer()
    }

    /// The Bind compliance of a bound vertex of `strength`: the type's
    /// compliance ÷ the strength, and for a muscle that holds its shape
    /// also ÷ [`MuscleParams::hold_strength`] at its activation.
    pub fn bind_compliance(&self, strength: f32) -> f32 {
        let hold = if self.holds_shape() {
            self.params.hold_strength(self.params.activation)
        } else {
            1.0
        };
        self.params.compliance.bind / (strength * hold)
    }

    /// Writes [`Muscle::bind_compliance`] into every Bind constraint.
    fn apply_bind_compliances(&mut self) {
        let base = self.bind_compliance(1.0);
        let k = &mut self.constraints.bind;
        for (c, b) in k.compliance.iter_mut().zip(&self.binding) {
            *c = base / b.strength;
        }
    }

    /// Pushes per-type compliances from `params` into the batches (after a
    /// parameter edit; no rebuild needed).
    pub fn apply_compliances(&mut self) {
        let p = self.params.compliance;
        let area = self.area_compliance();
        let k = &mut self.constraints;
        k.fiber.compliance = p.fiber;
        k.branch.compliance = p.branch;
        k.internal.compliance = p.internal;
        k.area.compliance = area;
        k.attach.compliance.fill(p.attach);
        k.branch_attach.compliance.fill(p.branch_attach);
        self.apply_bind_compliances();
        let volume = self.volume_compliance();
        if let Some(v) = &mut self.constraints.volume {
            v.compliance = volume;
        }
        self.pin_attachments();
        self.relink_weights();
    }

    /// Gives particles held with zero compliance an inverse mass of 0 (they
    /// move with their bone, see [`Muscle::place_pinned`]) and restores the
    /// others' masses. A hard attachment then holds exactly whatever the other
    /// constraints do after it in the iteration.
    pub fn pin_attachments(&mut self) {
        for a in &self.attachments {
            let v = a.vertex.index();
            self.w[v] = self.free_w[v];
            if let Some(ip) = a.internal_particle {
                self.w[ip.index()] = self.free_w[ip.index()];
            }
        }
        for a in &self.attachments {
            if self.params.compliance.attach == 0.0 {
                self.w[a.vertex.index()] = 0.0;
            }
            if let Some(ip) = a.internal_particle
                && self.params.compliance.branch_attach == 0.0
            {
                self.w[ip.index()] = 0.0;
            }
        }
    }

    /// Moves pinned particles' predictions to their attachment goals.
    pub fn place_pinned(&mut self) {
        let mut k = 0;
        for (i, a) in self.attachments.iter().enumerate() {
            if self.w[a.vertex.index()] == 0.0 {
                self.p[a.vertex.index()] = self.constraints.attach.goal[i];
            }
            if let Some(ip) = a.internal_particle {
                if self.w[ip.index()] == 0.0 {
                    self.p[ip.index()] = self.constraints.branch_attach.goal[k];
                }
                k += 1;
            }
        }
    }

    /// Per-vertex connection weights `(sliding, soft, hard)`, normalised if asked.
    pub fn connection_weights(&self, v: usize) -> (f32, f32, f32) {
        let d = self.params.weights;
        let pick = |map: &Option<Vec<f32>>, default: f32| map.as_ref().map_or(default, |m| m[v]);
        let (s, o, h) = (
            pick(&self.maps.sliding, d.sliding),
            pick(&self.maps.soft, d.soft),
            pick(&self.maps.hard, d.hard),
        );
        let sum = s + o + h;
        if d.normalize && sum > 0.0 {
            (s / sum, o / sum, h / sum)
        } else {
            (s, o, h)
        }
    }

    /// Recomputes the per-constraint compliances of Sliding / Soft / Hard from
    /// type compliances and weights (`α / weight`; weight 0 disables, and so
    /// does a vertex out of every target's reach).
    pub fn relink_weights(&mut self) {
        self.touch_topology();
        let comp = self.params.compliance;
        let weighted = |alpha: f32, w: f32| if w > 0.0 { alpha / w } else { f32::INFINITY };
        for i in 0..self.constraints.sliding.len() {
            let v = self.constraints.sliding.particle[i].index();
            let (s, o, h) = self.connection_weights(v);
            let c = &self.constraints;
            let on = |connected: Option<bool>, weight: f32| {
                if connected == Some(false) {
                    0.0
                } else {
                    weight
                }
            };
            let s = on(c.sliding.connected.get(i).copied(), s);
            let o = on(c.soft_anchor.get(i).map(|a| a.connected), o);
            let h = on(c.hard_anchor.get(i).map(|a| a.connected), h);
            self.constraints.sliding.compliance[i] = weighted(comp.sliding, s);
            self.constraints.soft.compliance[i] = weighted(comp.soft, o);
            self.constraints.hard.compliance[i] = weighted(comp.hard, h);
        }
    }

    /// Surface vertex positions (start of frame).
    pub fn surface_positions(&self) -> &[Vec3] {
        &self.x[..self.surface_count]
    }

    /// Internal point positions (start of frame).
    pub fn internal_positions(&self) -> &[Vec3] {
        &self.x[self.surface_count..]
    }

    /// Constraint counts per type.
    pub fn counts(&self) -> ConstraintCounts {
        self.constraints.counts()
    }

    /// Current enclosed volume of the surface (f64).
    pub fn volume(&self) -> f64 {
        let mesh = &self.mesh;
        crate::mesh::polygon_volume(
            &mesh.polygon_offsets,
            &mesh.polygon_indices,
            self.surface_positions(),
        )
    }

    /// Rest (start-frame) volume.
    pub fn rest_volume(&self) -> f64 {
        self.mesh.volume()
    }
}

/// Index of the point nearest `q` (0 for an empty slice).
pub fn nearest_vertex(points: &[Vec3], q: Vec3) -> u32 {
    (0..points.len())
        .min_by(|&a, &b| {
            points[a]
                .distance_squared(q)
                .total_cmp(&points[b].distance_squared(q))
        })
        .unwrap_or(0) as u32
}
