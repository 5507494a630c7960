//! A muscle — or any deformable body, such as a surface layer
//! ([`MuscleParams::surface_layer`]) — as plain data: particles, masses,
//! internal structure, fibres and constraints (SPEC §2, §5, §7), built by
//! [`Muscle::build`]. Target connections (Sliding, Soft, Hard) are linked by
//! the solver once every target exists; what the solver derives from a
//! muscle lives in its workspace, not here.

mod attachment_groups;
mod binding;
mod build;
mod constraints;
mod desc;
mod fiber;
mod held_rest;
mod hold_curve;
mod hold_line;
mod internal;
mod line_shape;
mod mass;
mod params;
mod tuning;

pub(crate) use attachment_groups::{farthest_pair, group_centroids};
pub(crate) use binding::update_bind_goals_in;
pub use binding::{BoundVertex, MAX_BONES, SkinBindingDesc, bind_constraints, update_bind_goals};
pub use build::{area_triangles, branch_links, fiber_edges, internal_links};
pub(crate) use constraints::{BATCHED_KINDS, MuscleLambdas};
pub use constraints::{Compliances, ConstraintCounts, ConstraintKind, MuscleConstraints};
pub(crate) use desc::held_by;
pub use desc::{AttachmentDesc, MuscleDesc, Roots, TargetRef, VertexMaps};
pub use fiber::{fiber_field, longest_axis};
pub use hold_line::{HoldLine, LinePose};
pub use internal::{InternalStructure, InternalStructureParams};
pub use line_shape::LineShape;
pub use params::{ConnectionWeights, HoldFrame, MAX_FIBER_SMOOTHING, MassMode, MuscleParams};

use crate::constraints::{ActivationScale, ParticleId, TargetSlot};
use crate::error::BuildError;
use crate::mesh::SurfaceMesh;
use glam::{Affine3A, Vec3};

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
    /// The line of action a held shape follows
    /// ([`MuscleParams::hold_frame`] [`HoldFrame::Line`]); `None`: the
    /// binding's bones carry it.
    pub hold_line: Option<HoldLine>,
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
