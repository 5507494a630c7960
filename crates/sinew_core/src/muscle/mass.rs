//! Particle masses: the muscle as a solid, lumped onto its particles.
//!
//! With [`MassMode::Density`] the muscle's mass `ρ V` is spread as a solid
//! body's would be. Every surface triangle `(a, b, c)` spans a tetrahedron
//! to the medulla — its apex `q̄` the mean of its vertices' internal points —
//! whose mass goes to its corners: a share `s` to the internal points (a
//! third of it each), the rest to `a`, `b` and `c`. The sum is scaled to
//! `ρ V`.
//!
//! ```text
//! V_t = |(b − a) × (c − a) · (q̄ − a)| / 6
//! m_a, m_b, m_c += ρ' V_t (1 − s) / 3      m_q(a), m_q(b), m_q(c) += ρ' V_t s / 3
//! ρ' = ρ V / Σ V_t,   s = 0.1
//! ```
//!
//! Why it matters: a vertex's mass follows the volume behind it (a cone to
//! the axis), not its surface area, and an internal point carries a share
//! of its ring's slice, more than a vertex linked to it. With the mass spread
//! by area and each internal point given a mean vertex mass, P3's biceps,
//! with no gravity and no targets, started from rest and reached 27 mm/s: a
//! self-excited oscillation of the two rings around the point where the
//! bands from its head and belly roots meet (5 iterations; stable with 20,
//! with Jacobi, or with internal points 3× heavier). Any share from 5 % up
//! keeps it at rest. A linear tetrahedron would lump a quarter on each
//! corner; a tenth keeps the heavy medulla from lagging under the Jacobi
//! average, which carries it only slowly (P3 under gravity at 5 iterations
//! settled with edges at ×1.38 under Jacobi with a quarter, ×1.18 with a
//! tenth; the Gauss–Seidel methods agree either way).
//!
//! Without an internal structure the mass is spread by one-ring area, as
//! before. [`MassMode::AreaDensity`] (a thin layer) gives each vertex its
//! one-ring area times the layer's mass per area; [`MassMode::Uniform`]
//! gives every particle the same mass.

use super::{InternalStructure, MassMode, MuscleParams, VertexMaps};
use crate::mesh::SurfaceMesh;

/// Inverse masses of the surface vertices, then the internal points, in a
/// scene of `length_unit` scene units per metre (densities are per cubic
/// or square metre; the mesh's volume and areas are in scene units).
pub(super) fn inverse_masses(
    mesh: &SurfaceMesh,
    structure: &InternalStructure,
    params: &MuscleParams,
    maps: &VertexMaps,
    length_unit: f32,
) -> Vec<f32> {
    let n = mesh.vertex_count();
    let internal = structure.points.len();
    let unit = f64::from(length_unit);
    let mut mass = match params.mass {
        MassMode::Uniform(m) => vec![m; n + internal],
        MassMode::Density(rho) if internal > 0 && structure.vertex_point.len() == n => {
            lumped_solid(mesh, structure, f64::from(rho) / (unit * unit * unit))
        }
        MassMode::Density(rho) => {
            let area = vertex_areas(mesh);
            let sum: f64 = area.iter().sum();
            let total = f64::from(rho) / (unit * unit * unit) * mesh.volume().abs();
            area.iter().map(|&a| (total * a / sum) as f32).collect()
        }
        MassMode::AreaDensity(sigma) => vertex_areas(mesh)
            .iter()
            .map(|&a| (f64::from(sigma) / (unit * unit) * a) as f32)
            .collect(),
    };
    if let Some(mult) = &maps.mass {
        for (m, k) in mass.iter_mut().zip(mult) {
            *m *= k.max(1e-6);
        }
    }
    mass.into_iter()
        .map(|m| {
            if m > 0.0 && m.is_finite() {
                1.0 / m
            } else {
                1.0
            }
        })
        .collect()
}

/// The share of each cone's mass the medulla takes.
const MEDULLA_SHARE: f64 = 0.1;

/// The surface's cone tetrahedra to the medulla, lumped (module docs).
fn lumped_solid(mesh: &SurfaceMesh, structure: &InternalStructure, rho: f64) -> Vec<f32> {
    let n = mesh.vertex_count();
    let mut mass = vec![0.0f64; n + structure.points.len()];
    let mut total = 0.0f64;
    for &tri in &mesh.triangles {
        let [a, b, c] = tri.map(|v| mesh.positions[v as usize].as_dvec3());
        let points = tri.map(|v| structure.vertex_point[v as usize] as usize);
        let apex = points
            .iter()
            .map(|&k| structure.points[k].as_dvec3())
            .sum::<glam::DVec3>()
            / 3.0;
        let volume = ((b - a).cross(c - a).dot(apex - a) / 6.0).abs();
        total += volume;
        for v in tri {
            mass[v as usize] += volume * (1.0 - MEDULLA_SHARE) / 3.0;
        }
        for k in points {
            mass[n + k] += volume * MEDULLA_SHARE / 3.0;
        }
    }
    let scale = if total > 0.0 {
        rho * mesh.volume().abs() / total
    } else {
        0.0
    };
    mass.into_iter().map(|m| (m * scale) as f32).collect()
}

/// `ρ V_rest` spread over the surface vertices by one-ring area.
/// Each vertex's share of the surface: a third of its triangles' areas.
fn vertex_areas(mesh: &SurfaceMesh) -> Vec<f64> {
    let mut area = vec![0.0f64; mesh.vertex_count()];
    for &[a, b, c] in &mesh.triangles {
        let [pa, pb, pc] = [a, b, c].map(|v| mesh.positions[v as usize]);
        let t = 0.5 * f64::from((pb - pa).cross(pc - pa).length()) / 3.0;
        area[a as usize] += t;
        area[b as usize] += t;
        area[c as usize] += t;
    }
    area
}

#[cfg(test)]
mod tests {
    use crate::scene::builtin;
    use std::path::Path;

    #[test]
    fn a_solid_muscle_weighs_rho_v_and_its_internal_points_carry_their_slices() {
        let solver = builtin("P3").unwrap().instantiate(Path::new(".")).unwrap();
        for m in solver.muscles() {
            let masses: Vec<f64> = m.free_w.iter().map(|&w| 1.0 / f64::from(w)).collect();
            let total: f64 = masses.iter().sum();
            let expected = 1060.0 * m.rest_volume();
            assert!(
                (total - expected).abs() < 1e-4 * expected,
                "{total} vs {expected}"
            );
            // Every internal point is heavier than the vertices linked to it.
            let n = m.surface_count;
            for (k, &point) in masses[n..].iter().enumerate() {
                let linked: Vec<f64> = (0..n)
                    .filter(|&v| m.structure.vertex_point[v] as usize == k)
                    .map(|v| masses[v])
                    .collect();
                if linked.len() < 3 {
                    continue;
                }
                let mean = linked.iter().sum::<f64>() / linked.len() as f64;
                assert!(point > mean, "{} point {k}: {point} vs {mean}", m.name);
            }
        }
    }
}
