//! [`Muscle::build`]: particles, masses, internal structure, fibres and
//! the muscle's own constraints from a [`MuscleDesc`].

use super::*;
use crate::constraints::{ActivationRest, AreaBatch, DistanceBatch, ParticleId, VolumeConstraint};
use fiber::fiber_field;

impl Muscle {
    /// Builds a muscle in a scene of `length_unit` scene units per metre
    /// ([`crate::SolverSettings::length_unit`], `1` for metres).
    /// `bone_transform(i)` gives bone `i`'s start-frame transform.
    pub fn build(
        desc: MuscleDesc,
        length_unit: f32,
        bone_transform: impl Fn(usize) -> Affine3A,
    ) -> Result<Self, BuildError> {
        let MuscleDesc {
            name,
            mesh,
            roots,
            attachments,
            targets,
            params,
            maps,
            binding,
        } = desc;
        params.validate(&name)?;
        if !(length_unit > 0.0 && length_unit.is_finite()) {
            return Err(BuildError::InvalidParameter {
                muscle: name,
                parameter: "length_unit".into(),
                value: length_unit,
                reason: "must be finite and > 0 (scene units per metre)".into(),
            });
        }
        let n = mesh.vertex_count();
        for (map, len) in [
            ("sliding", maps.sliding.as_ref().map(Vec::len)),
            ("soft", maps.soft.as_ref().map(Vec::len)),
            ("hard", maps.hard.as_ref().map(Vec::len)),
            ("fibers", maps.fibers.as_ref().map(Vec::len)),
            ("mass", maps.mass.as_ref().map(Vec::len)),
            ("tendon", maps.tendon.as_ref().map(Vec::len)),
            ("damping", maps.damping.as_ref().map(Vec::len)),
            ("thickness", maps.thickness.as_ref().map(Vec::len)),
        ] {
            if let Some(len) = len.filter(|&l| l != n) {
                return Err(BuildError::MapLength {
                    muscle: name.clone(),
                    map: map.into(),
                    len,
                    count: n,
                });
            }
        }
        maps.validate(&name)?;
        let report = mesh.report();
        let closed = report.is_closed_manifold();
        if params.volume.enabled && !closed && !params.volume.allow_open_mesh {
            return Err(BuildError::Mesh(
                report
                    .into_result(&mesh.source)
                    .expect_err("mesh is not closed"),
            ));
        }
        if closed && report.volume < 0.0 {
            return Err(BuildError::Mesh(crate::MeshError::InsideOut {
                file: mesh.source.clone(),
                volume: report.volume,
            }));
        }
        if !report.non_manifold_edges.is_empty() {
            return Err(BuildError::Mesh(
                report.into_result(&mesh.source).expect_err("non-manifold"),
            ));
        }
        // Attachment vertices: one per attachment (its root), plus the rest
        // of a region's.
        let (attach_vertices, held) = held_by(&attachments, &mesh.positions, &name)?;
        // Roots.
        let root_list: Vec<u32> = match &roots {
            Roots::Vertices(v) => v.clone(),
            Roots::Attachments => attach_vertices.clone(),
            Roots::LongestAxisTips => {
                let axis = longest_axis(&mesh.positions);
                let key = |i: &usize| mesh.positions[*i].dot(axis);
                let lo = (0..n).min_by(|a, b| key(a).total_cmp(&key(b))).unwrap_or(0);
                let hi = (0..n).max_by(|a, b| key(a).total_cmp(&key(b))).unwrap_or(0);
                vec![lo as u32, hi as u32]
            }
        };
        if let Some(&vertex) = root_list.iter().find(|&&r| r as usize >= n) {
            return Err(BuildError::RootOutOfRange {
                muscle: name,
                vertex,
                count: n,
            });
        }
        if params.internal.enabled && root_list.is_empty() {
            return Err(BuildError::NoRoots {
                muscle: name,
                reason: match roots {
                    Roots::Attachments => "roots = Attachments but the muscle has no attachments",
                    _ => "the root list is empty",
                }
                .into(),
            });
        }
        let structure = if params.internal.enabled {
            InternalStructure::build(&mesh, &root_list, &params.internal)
        } else {
            InternalStructure::default()
        };
        // Fibres.
        let mut fibers = fiber_field(
            &mesh,
            params.internal.enabled.then_some(&structure),
            params.fiber_smoothing,
        );
        if let Some(over) = &maps.fibers {
            for (f, o) in fibers.iter_mut().zip(over) {
                if let Some(o) = o.try_normalize() {
                    *f = o;
                }
            }
        }
        fibers.extend_from_slice(&structure.tangents);
        // Particles.
        let mut rest = mesh.positions.clone();
        rest.extend_from_slice(&structure.points);
        // A held shape (the binding the solver or this build makes for
        // `hold_shape`, not a skin's) may follow the line of action.
        let hold_line = (params.hold_shape && binding.as_ref().is_none_or(|b| b.holds_shape))
            .then(|| hold_line::for_frame(params.hold_frame, &rest, &held, &bone_transform))
            .flatten();
        let binding = binding.or_else(|| {
            params
                .hold_shape
                .then(|| SkinBindingDesc::holding_shape(&mesh.positions, &held, &[]))
                .flatten()
        });
        let binding = match &binding {
            Some(desc) => desc.resolve(&name, &mesh.positions, &bone_transform)?,
            None => Vec::new(),
        };
        let w = mass::inverse_masses(&mesh, &structure, &params, &maps, length_unit);
        let nparticles = rest.len();
        let mut muscle = Self {
            name,
            params,
            mesh,
            structure,
            roots: root_list,
            fibers,
            x: rest.clone(),
            p: rest.clone(),
            v: vec![Vec3::ZERO; nparticles],
            free_w: w.clone(),
            w,
            rest,
            surface_count: n,
            attachments: Vec::new(),
            binding,
            hold_line,
            targets,
            constraints: MuscleConstraints::default(),
            maps,
            activation_reported: false,
            length_unit,
            topology: 0,
        };
        muscle.build_own_constraints(closed);
        for (bone, v) in held {
            muscle.add_attachment(bone, v, &bone_transform);
        }
        muscle.pin_attachments();
        muscle.update_activation();
        Ok(muscle)
    }

    /// Makes the constraints the table builds (Fiber, Branch, Internal)
    /// and Volume.
    fn build_own_constraints(&mut self, closed: bool) {
        self.build_table_constraints();
        let (p, n) = (&self.params, self.surface_count);
        let compliance = self.volume_compliance();
        if p.volume.enabled && closed {
            self.constraints.volume = Some(VolumeConstraint {
                polygon_offsets: self.mesh.polygon_offsets.clone(),
                polygon_indices: self.mesh.polygon_indices.clone(),
                surface_count: n,
                rest_volume: self.mesh.volume(),
                ratio: 1.0,
                compliance,
                lambda: 0.0,
                gradient: Vec::with_capacity(n),
                relative: Vec::with_capacity(n),
                ..Default::default()
            });
        }
    }
}

/// The Fiber constraints of `m`: one per polygon edge of its surface, at
/// the edge's rest length, shortened along the fibres with activation.
pub fn fiber_edges(m: &Muscle) -> DistanceBatch {
    let edges = m.mesh.edges.iter().copied();
    distances_at_rest(m, m.params.compliance.fiber, true, edges)
}

/// The Area constraints of `m`: for a surface layer
/// ([`MuscleParams::is_surface_layer`]) one per triangle of its mesh at the
/// triangle's rest area, and for a polygon of more vertices one per corner
/// (`p_k−1, p_k, p_k+1`: symmetric, where a split along one diagonal would
/// favour it). None for a muscle: its volume and internal structure hold
/// its shape.
pub fn area_triangles(m: &Muscle) -> AreaBatch {
    let mut batch = AreaBatch {
        compliance: m.area_compliance(),
        mode: m.params.area_mode,
        ..Default::default()
    };
    if !m.params.is_surface_layer() {
        return batch;
    }
    let id = |v: u32| ParticleId::from_index(v as usize);
    for o in m.mesh.polygon_offsets.windows(2) {
        let poly = &m.mesh.polygon_indices[o[0] as usize..o[1] as usize];
        let k = poly.len();
        let corners = if k == 3 { 1 } else { k };
        for j in 0..corners {
            let tri = [poly[(j + k - 1) % k], poly[j], poly[(j + 1) % k]];
            let [a, b, c] = tri.map(|v| m.rest[v as usize]);
            batch.push(tri.map(id), AreaBatch::triangle_area(a, b, c));
        }
    }
    batch
}

/// The Branch constraints of `m`: one per branch of its internal
/// structure (none without one), following activation when
/// [`MuscleParams::branch_follows_activation`] is set.
pub fn branch_links(m: &Muscle) -> DistanceBatch {
    let first = m.surface_count as u32;
    let branches = (m.structure.branches.iter()).map(|&[a, b]| [first + a, first + b]);
    let follows = m.params.branch_follows_activation;
    internal_distances(m, m.params.compliance.branch, follows, branches)
}

/// The Internal constraints of `m`: each surface vertex to its internal
/// point (none without an internal structure), following activation when
/// [`MuscleParams::internal_follows_activation`] is set.
pub fn internal_links(m: &Muscle) -> DistanceBatch {
    let first = m.surface_count as u32;
    let points = &m.structure.vertex_point;
    let links = (0..first).map(|v| [v, first + points[v as usize]]);
    let follows = m.params.internal_follows_activation;
    internal_distances(m, m.params.compliance.internal, follows, links)
}

/// Distance constraints between `pairs` of the internal structure's
/// particles, or none when `m` has no structure.
fn internal_distances(
    m: &Muscle,
    compliance: f32,
    follows_activation: bool,
    pairs: impl Iterator<Item = [u32; 2]>,
) -> DistanceBatch {
    if m.params.internal.enabled && !m.structure.points.is_empty() {
        distances_at_rest(m, compliance, follows_activation, pairs)
    } else {
        DistanceBatch {
            compliance,
            ..Default::default()
        }
    }
}

/// A batch of distance constraints between `pairs` at their rest lengths,
/// whose rest lengths follow activation when `follows_activation`, ordered
/// in runs that share no particle ([`DistanceBatch::arrange_in_runs`]:
/// Gauss–Seidel overlaps their projections).
fn distances_at_rest(
    m: &Muscle,
    compliance: f32,
    follows_activation: bool,
    pairs: impl Iterator<Item = [u32; 2]>,
) -> DistanceBatch {
    let mut batch = DistanceBatch {
        compliance,
        ..Default::default()
    };
    let tendon = m.maps.tendon.as_deref();
    let act = push_at_rest(&mut batch, pairs, &m.rest, &m.fibers, tendon);
    if follows_activation {
        batch.activation = Some(act);
    }
    batch.arrange_in_runs();
    batch
}

/// Pushes a distance constraint between each pair of particles onto
/// `batch` at its rest length, and returns what its activation-driven rest
/// length needs (the rest edge and the fibre across it, per constraint, and
/// with a tendon mask — one value per surface vertex; particles past them
/// are internal, belly — how contractile it is).
fn push_at_rest(
    batch: &mut DistanceBatch,
    pairs: impl Iterator<Item = [u32; 2]>,
    rest: &[Vec3],
    fibers: &[Vec3],
    tendon: Option<&[f32]>,
) -> ActivationRest {
    let mut act = ActivationRest::default();
    let mask = |i: u32| {
        tendon
            .and_then(|t| t.get(i as usize))
            .copied()
            .unwrap_or(0.0)
    };
    for [a, b] in pairs {
        if tendon.is_some() {
            act.contractile.push(1.0 - 0.5 * (mask(a) + mask(b)));
        }
        let (pa, pb) = (rest[a as usize], rest[b as usize]);
        batch.push(ParticleId::new(a), ParticleId::new(b), pa.distance(pb));
        let fiber = ActivationRest::edge_fiber(fibers[a as usize], fibers[b as usize]);
        act.push(pa - pb, fiber);
    }
    act
}
