//! Procedural closed quad meshes: UV ellipsoids, subdivided boxes and fusiform
//! (spindle-shaped) muscles, optionally with two heads joining one belly.
//!
//! All generators return closed, manifold, outward-oriented meshes whose quads
//! run along and across the long axis, as an artist's muscle mesh would.

use super::{SurfaceMesh, signed_volume};
use crate::error::MeshError;
use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};
use std::f32::consts::{PI, TAU};

/// Generators the scene format can name instead of a mesh file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum MeshGenerator {
    /// UV ellipsoid along +X (poles on the X axis): `segments` around,
    /// `stacks` from pole to pole. 10×10 gives the thesis' 92-vertex oval.
    Ellipsoid {
        /// Centre. Units: m.
        center: Vec3,
        /// Semi-axes. Units: m.
        radii: Vec3,
        /// Vertices around each ring.
        segments: u32,
        /// Stacks pole to pole (rings = stacks − 1).
        stacks: u32,
    },
    /// Box surface subdivided into a quad grid.
    Box {
        /// Centre. Units: m.
        center: Vec3,
        /// Full size along each axis. Units: m.
        size: Vec3,
        /// Quads along each axis.
        divisions: [u32; 3],
    },
    /// Spindle along +X from `start`, belly in the middle, pointed tendon tips.
    Fusiform {
        /// First tip. Units: m.
        start: Vec3,
        /// Second tip. Units: m.
        end: Vec3,
        /// Belly radius. Units: m.
        belly_radius: f32,
        /// Radius near the tips. Units: m.
        tendon_radius: f32,
        /// Vertices around.
        around: u32,
        /// Rings between the tips.
        rings: u32,
    },
    /// One belly (from `end` towards the junction) splitting into two heads
    /// ending at `head_a` and `head_b` — a real bifurcation, like the biceps.
    Bifurcated {
        /// Distal tendon tip. Units: m.
        end: Vec3,
        /// Where the belly splits. Units: m.
        junction: Vec3,
        /// Tip of the first head. Units: m.
        head_a: Vec3,
        /// Tip of the second head. Units: m.
        head_b: Vec3,
        /// Belly radius. Units: m.
        belly_radius: f32,
        /// Head radius. Units: m.
        head_radius: f32,
        /// Vertices around each head is `half_around + 2`; the belly has `2 × half_around`.
        half_around: u32,
        /// Rings in the belly (including the junction ring).
        belly_rings: u32,
        /// Rings in each head.
        head_rings: u32,
    },
}

impl MeshGenerator {
    /// The same generator moved by `offset` (units: m).
    pub fn translated(&self, offset: Vec3) -> Self {
        let mut moved = self.clone();
        match &mut moved {
            Self::Ellipsoid { center, .. } | Self::Box { center, .. } => *center += offset,
            Self::Fusiform { start, end, .. } => {
                *start += offset;
                *end += offset;
            }
            Self::Bifurcated {
                end,
                junction,
                head_a,
                head_b,
                ..
            } => {
                for p in [end, junction, head_a, head_b] {
                    *p += offset;
                }
            }
        }
        moved
    }

    /// Builds the mesh. `name` appears in error messages.
    pub fn build(&self, name: &str) -> Result<SurfaceMesh, MeshError> {
        let source = format!("<generated {name}>");
        let bad = |reason: &str| MeshError::DegenerateFace {
            file: source.clone().into(),
            face: 0,
            reason: format!("generator parameters: {reason}"),
        };
        let checked = |points: &[Vec3], lengths: &[f32], vertices: u64| match out_of_bounds(
            points, lengths, vertices,
        ) {
            Some(reason) => Err(bad(&reason)),
            None => Ok(()),
        };
        let (positions, polygons) = match *self {
            Self::Ellipsoid {
                center,
                radii,
                segments,
                stacks,
            } => {
                let vertices = u64::from(segments) * u64::from(stacks.saturating_sub(1)) + 2;
                checked(&[center, radii], &[], vertices)?;
                if segments < 3 || stacks < 2 || radii.min_element() <= 0.0 {
                    return Err(bad("need segments ≥ 3, stacks ≥ 2, radii > 0"));
                }
                ellipsoid(center, radii, segments, stacks)
            }
            Self::Box {
                center,
                size,
                divisions,
            } => {
                let [a, b, c] = divisions.map(|d| u64::from(d) + 1);
                checked(&[center, size], &[], 2 * (a * b + b * c + c * a))?;
                if divisions.contains(&0) || size.min_element() <= 0.0 {
                    return Err(bad("need divisions ≥ 1 and size > 0"));
                }
                subdivided_box(center, size, divisions)
            }
            Self::Fusiform {
                start,
                end,
                belly_radius,
                tendon_radius,
                around,
                rings,
            } => {
                let vertices = u64::from(around) * u64::from(rings) + 2;
                checked(&[start, end], &[belly_radius, tendon_radius], vertices)?;
                if around < 3 || rings < 1 || belly_radius <= 0.0 || tendon_radius <= 0.0 {
                    return Err(bad("need around ≥ 3, rings ≥ 1, radii > 0"));
                }
                if start.distance(end) <= 0.0 {
                    return Err(bad("start and end coincide"));
                }
                fusiform(start, end, belly_radius, tendon_radius, around, rings)
            }
            Self::Bifurcated {
                end,
                junction,
                head_a,
                head_b,
                belly_radius,
                head_radius,
                half_around,
                belly_rings,
                head_rings,
            } => {
                let rings = u64::from(belly_rings) + 2 * u64::from(head_rings);
                checked(
                    &[end, junction, head_a, head_b],
                    &[belly_radius, head_radius],
                    2 * u64::from(half_around) * rings + 3,
                )?;
                if half_around < 2 || belly_rings < 1 || head_rings < 1 {
                    return Err(bad("need half_around ≥ 2, rings ≥ 1"));
                }
                if belly_radius <= 0.0 || head_radius <= 0.0 {
                    return Err(bad("radii must be > 0"));
                }
                bifurcated(
                    end,
                    junction,
                    [head_a, head_b],
                    belly_radius,
                    head_radius,
                    half_around,
                    belly_rings,
                    head_rings,
                )
            }
        };
        let polygons = oriented_outward(&positions, polygons);
        SurfaceMesh::new(source, positions, &polygons)
    }
}

/// Why a generator's parameters cannot make a mesh of sane size: a
/// coordinate or length that is not finite, or more than
/// [`MAX_GENERATED_VERTICES`] vertices (`vertices` is counted in 64 bits, so
/// no count overflows).
fn out_of_bounds(points: &[Vec3], lengths: &[f32], vertices: u64) -> Option<String> {
    let floats = points
        .iter()
        .flat_map(|p| p.to_array())
        .chain(lengths.iter().copied());
    if let Some(x) = floats.into_iter().find(|x| !x.is_finite()) {
        return Some(format!("a coordinate or radius is {x}, expected finite"));
    }
    (vertices > MAX_GENERATED_VERTICES).then(|| {
        format!(
            "about {vertices} vertices, more than the {MAX_GENERATED_VERTICES} a generator makes"
        )
    })
}

/// Most vertices a [`MeshGenerator`] makes (a typo such as `segments:
/// 100000` would otherwise allocate gigabytes).
pub const MAX_GENERATED_VERTICES: u64 = 200_000;

/// Flips every polygon when the signed volume is negative.
pub(crate) fn oriented_outward(positions: &[Vec3], mut polygons: Vec<Vec<u32>>) -> Vec<Vec<u32>> {
    if signed_volume(&fan_triangles(&polygons), positions) < 0.0 {
        for p in &mut polygons {
            p.reverse();
        }
    }
    polygons
}

/// Each polygon fanned from its first vertex into triangles.
pub(crate) fn fan_triangles(polygons: &[Vec<u32>]) -> Vec<[u32; 3]> {
    polygons
        .iter()
        .flat_map(|p| (1..p.len() - 1).map(move |k| [p[0], p[k], p[k + 1]]))
        .collect()
}

/// Quads between consecutive rings of equal length, plus pole fans at both ends.
pub(crate) fn tube(
    rings: &[Vec<u32>],
    first_pole: Option<u32>,
    last_pole: Option<u32>,
) -> Vec<Vec<u32>> {
    let mut polys = Vec::new();
    for pair in rings.windows(2) {
        let (r0, r1) = (&pair[0], &pair[1]);
        let n = r0.len();
        for j in 0..n {
            let k = (j + 1) % n;
            polys.push(vec![r0[j], r0[k], r1[k], r1[j]]);
        }
    }
    if let (Some(pole), Some(ring)) = (first_pole, rings.first()) {
        let n = ring.len();
        for j in 0..n {
            polys.push(vec![pole, ring[(j + 1) % n], ring[j]]);
        }
    }
    if let (Some(pole), Some(ring)) = (last_pole, rings.last()) {
        let n = ring.len();
        for j in 0..n {
            polys.push(vec![pole, ring[j], ring[(j + 1) % n]]);
        }
    }
    polys
}

type Raw = (Vec<Vec3>, Vec<Vec<u32>>);

fn ellipsoid(center: Vec3, radii: Vec3, segments: u32, stacks: u32) -> Raw {
    let mut positions = vec![center - Vec3::X * radii.x];
    let mut rings = Vec::new();
    for i in 1..stacks {
        let theta = PI * i as f32 / stacks as f32;
        let mut ring = Vec::new();
        for j in 0..segments {
            let phi = TAU * j as f32 / segments as f32;
            ring.push(positions.len() as u32);
            positions.push(
                center
                    + Vec3::new(
                        -radii.x * theta.cos(),
                        radii.y * theta.sin() * phi.cos(),
                        radii.z * theta.sin() * phi.sin(),
                    ),
            );
        }
        rings.push(ring);
    }
    let last = positions.len() as u32;
    positions.push(center + Vec3::X * radii.x);
    let polys = tube(&rings, Some(0), Some(last));
    (positions, polys)
}

fn subdivided_box(center: Vec3, size: Vec3, div: [u32; 3]) -> Raw {
    // Grid points on the surface of a lattice, indexed by integer coordinates.
    let [nx, ny, nz] = div;
    let mut index = std::collections::HashMap::new();
    let mut positions = Vec::new();
    let mut id = |i: u32, j: u32, k: u32, positions: &mut Vec<Vec3>| -> u32 {
        *index.entry((i, j, k)).or_insert_with(|| {
            let t = Vec3::new(
                i as f32 / nx as f32,
                j as f32 / ny as f32,
                k as f32 / nz as f32,
            );
            positions.push(center + (t - 0.5) * size);
            positions.len() as u32 - 1
        })
    };
    let mut polys = Vec::new();
    // Six faces: (fixed axis, fixed value, u axis, v axis).
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [0, div[axis]] {
            for a in 0..div[u] {
                for b in 0..div[v] {
                    let corner = |da: u32, db: u32| {
                        let mut c = [0u32; 3];
                        c[axis] = side;
                        c[u] = a + da;
                        c[v] = b + db;
                        c
                    };
                    let mut quad: Vec<u32> =
                        [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)]
                            .iter()
                            .map(|c| id(c[0], c[1], c[2], &mut positions))
                            .collect();
                    if side == 0 {
                        quad.reverse();
                    }
                    polys.push(quad);
                }
            }
        }
    }
    (positions, polys)
}

/// Radius profile of a fusiform muscle at parameter `t ∈ [0, 1]`.
pub(crate) fn spindle(t: f32, belly: f32, tendon: f32) -> f32 {
    tendon + (belly - tendon) * (PI * t).sin().powf(1.5)
}

/// Orthonormal basis `(u, v)` perpendicular to `axis`.
pub(crate) fn perpendicular_basis(axis: Vec3) -> (Vec3, Vec3) {
    let helper = if axis.y.abs() < 0.9 { Vec3::Y } else { Vec3::Z };
    let u = axis.cross(helper).normalize();
    (u, axis.cross(u))
}

fn fusiform(start: Vec3, end: Vec3, belly: f32, tendon: f32, around: u32, rings: u32) -> Raw {
    let axis = (end - start).normalize();
    let (u, v) = perpendicular_basis(axis);
    let mut positions = vec![start];
    let mut ring_ids = Vec::new();
    for i in 1..=rings {
        let t = i as f32 / (rings + 1) as f32;
        let c = start.lerp(end, t);
        let r = spindle(t, belly, tendon);
        let ring: Vec<u32> = (0..around)
            .map(|j| {
                let phi = TAU * j as f32 / around as f32;
                positions.push(c + r * (phi.cos() * u + phi.sin() * v));
                positions.len() as u32 - 1
            })
            .collect();
        ring_ids.push(ring);
    }
    positions.push(end);
    let last = positions.len() as u32 - 1;
    (positions, tube(&ring_ids, Some(0), Some(last)))
}

#[expect(clippy::too_many_arguments, reason = "mirrors the generator's fields")]
fn bifurcated(
    end: Vec3,
    junction: Vec3,
    heads: [Vec3; 2],
    belly: f32,
    head_radius: f32,
    half: u32,
    belly_rings: u32,
    head_rings: u32,
) -> Raw {
    let around = 2 * half;
    let axis = (junction - end).normalize();
    let (u, v) = perpendicular_basis(axis);
    // Belly: from the distal tip to the junction ring (the last belly ring).
    let mut positions = vec![end];
    let mut belly_ids: Vec<Vec<u32>> = Vec::new();
    for i in 1..=belly_rings {
        let t = i as f32 / belly_rings as f32;
        let c = end.lerp(junction, t);
        // Spindle over the belly; the junction keeps most of the belly radius.
        let r = spindle(0.5 * t + 0.05 * (1.0 - t), belly, head_radius * 0.5).max(head_radius);
        let ring: Vec<u32> = (0..around)
            .map(|j| {
                let phi = TAU * j as f32 / around as f32;
                positions.push(c + r * (phi.cos() * u + phi.sin() * v));
                positions.len() as u32 - 1
            })
            .collect();
        belly_ids.push(ring);
    }
    let junction_ring = belly_ids.last().expect("belly_rings ≥ 1").clone();
    let crotch = positions.len() as u32;
    positions.push(junction);
    let mut polys = tube(&belly_ids, Some(0), None);
    // Head loops: half of the junction ring plus the crotch vertex.
    let half = half as usize;
    let loops = [
        {
            let mut l: Vec<u32> = junction_ring[0..=half].to_vec();
            l.push(crotch);
            l
        },
        {
            let mut l: Vec<u32> = junction_ring[half..].to_vec();
            l.push(junction_ring[0]);
            l.push(crotch);
            l
        },
    ];
    for (head_loop, tip) in loops.into_iter().zip(heads) {
        let centre0 = head_loop
            .iter()
            .map(|&i| positions[i as usize])
            .sum::<Vec3>()
            / head_loop.len() as f32;
        let head_axis = (tip - centre0).normalize();
        let (hu, hv) = perpendicular_basis(head_axis);
        // Angle of each loop vertex around the head centre, in the head's frame.
        let angles: Vec<f32> = head_loop
            .iter()
            .map(|&i| {
                let d = positions[i as usize] - centre0;
                Vec2::new(d.dot(hu), d.dot(hv)).to_angle()
            })
            .collect();
        let mut rings = vec![head_loop.clone()];
        for i in 1..=head_rings {
            let t = i as f32 / (head_rings + 1) as f32;
            let c = centre0.lerp(tip, t);
            let r = head_radius * (1.0 - 0.75 * t * t);
            let ring: Vec<u32> = angles
                .iter()
                .map(|&phi| {
                    positions.push(c + r * (phi.cos() * hu + phi.sin() * hv));
                    positions.len() as u32 - 1
                })
                .collect();
            rings.push(ring);
        }
        let pole = positions.len() as u32;
        positions.push(tip);
        polys.extend(tube(&rings, None, Some(pole)));
    }
    (positions, polys)
}

/// The thesis' P1 oval: a 10×10 UV ellipsoid (92 vertices, 190 edges), 12 cm long.
pub fn thesis_oval(center: Vec3) -> MeshGenerator {
    MeshGenerator::Ellipsoid {
        center,
        radii: Vec3::new(0.06, 0.025, 0.025),
        segments: 10,
        stacks: 10,
    }
}
