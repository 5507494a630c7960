//! Where a swept muscle's rings go when its path runs through a bone: each
//! ring is moved within its own plane, and thinned where it must be, until
//! it lies outside the bones.
//!
//! A ring moved within its plane keeps the order and the planes the path
//! gave the rings: on a straight path the planes are parallel and the
//! surface between two rings stays between their planes, so the swept
//! surface cannot cross itself however far its rings move aside. Moving
//! each ring's centre to a radius from the nearest bone point in any
//! direction, as the importer did first, turned T5's centre lines by up to
//! 148° between neighbouring rings, moved two of the biceps' short head's
//! rings 43 and 51 mm, and left four of T5's muscles and 21 of T7's
//! crossing themselves at rest (the anconeus 136 pairs of triangles);
//! ARCHITECTURE.md, "Rings moved aside within their planes".

use crate::closest::TargetSurface;
use crate::mesh::primitives::perpendicular_basis;
use glam::Vec3;
use std::f32::consts::TAU;

/// Points sampled round a ring to test it against the bones.
const SAMPLES: usize = 12;

/// Directions within a ring's plane searched for a clear place.
const DIRECTIONS: usize = 24;

/// Radii tried between the full one and the thinnest, both included.
const THINNING_STEPS: usize = 4;

/// Farthest a ring's centre moves within its plane. Units: m.
const MAX_SHIFT: f32 = 0.05;

/// A ring's centre and radius clear of `bones`: the ring of centre `c`,
/// plane normal `normal` and radius `radius` goes to a place within its
/// plane where its centre and the points sampled round it lie outside
/// every bone and at least `margin` from them: of the places searched
/// (along [`DIRECTIONS`] directions, at most [`MAX_SHIFT`] away), the one
/// that moves it least plus differs least from `previous_shift` (the
/// previous ring's move), so that neighbouring rings move aside together
/// instead of each to its own nearest side. Where there is none (the path
/// passes between bones closer together than the ring is wide), the ring
/// is tried thinner, in steps down to `min_radius`; where even that fails,
/// it stays where it was at `min_radius` (the importer then pushes the
/// surface out vertex by vertex).
pub(super) fn clear_ring(
    c: Vec3,
    normal: Vec3,
    radius: f32,
    min_radius: f32,
    previous_shift: Vec3,
    margin: f32,
    bones: &[&TargetSurface],
) -> (Vec3, f32) {
    let previous = previous_shift - normal * previous_shift.dot(normal);
    let (u, v) = perpendicular_basis(normal);
    let min_radius = min_radius.min(radius);
    let cost = |shift: Vec3| shift.length() + shift.distance(previous);
    for k in 0..=THINNING_STEPS {
        let r = radius + (min_radius - radius) * k as f32 / THINNING_STEPS as f32;
        let ring = Ring {
            u,
            v,
            radius: r,
            margin,
        };
        // No move costs least: |x| + |x − previous| ≥ |previous| for any x.
        if ring.is_clear(c, bones) {
            return (c, r);
        }
        let step = (0.25 * r).max(margin).max(1e-4);
        // Candidates (staying is not one: it was just found not clear):
        // keeping the previous move, and along each direction the first
        // clear place and the one nearest the previous move.
        let mut candidates = vec![previous];
        for j in 0..DIRECTIONS {
            let phi = TAU * j as f32 / DIRECTIONS as f32;
            let d = phi.cos() * u + phi.sin() * v;
            let mut s = step;
            while s <= MAX_SHIFT {
                if ring.seems_clear(c + d * s, bones) {
                    candidates.push(d * s);
                    break;
                }
                s += step;
            }
            let along = previous.dot(d);
            if along > s {
                candidates.push(d * along);
            }
        }
        candidates.sort_by(|a, b| {
            cost(*a)
                .total_cmp(&cost(*b))
                .then(a.length().total_cmp(&b.length()))
        });
        if let Some(shift) = candidates
            .into_iter()
            .find(|&shift| ring.is_clear(c + shift, bones))
        {
            return (c + shift, r);
        }
    }
    (c, min_radius)
}

/// A ring's plane and size.
struct Ring {
    u: Vec3,
    v: Vec3,
    radius: f32,
    margin: f32,
}

impl Ring {
    /// The ring's centre and the points sampled round it, for a ring centred at `c`.
    fn samples(&self, c: Vec3) -> impl Iterator<Item = Vec3> + '_ {
        std::iter::once(c).chain((0..SAMPLES).map(move |j| {
            let phi = TAU * j as f32 / SAMPLES as f32;
            c + self.radius * (phi.cos() * self.u + phi.sin() * self.v)
        }))
    }

    /// Whether the ring centred at `c` and its centre lie outside every
    /// bone (by winding number) and at least `margin` from them.
    fn is_clear(&self, c: Vec3, bones: &[&TargetSurface]) -> bool {
        self.samples(c).all(|p| {
            bones
                .iter()
                .all(|b| b.closest_within(p, None, self.margin).is_none() && !b.contains(p))
        })
    }

    /// [`Ring::is_clear`] read from the side of the nearest surface point
    /// (its normal) instead of the winding number: many times cheaper, for
    /// the search; the place chosen is checked with [`Ring::is_clear`].
    fn seems_clear(&self, c: Vec3, bones: &[&TargetSurface]) -> bool {
        self.samples(c).all(|p| {
            bones.iter().all(|b| {
                b.lower_bound(p) > self.margin
                    || b.closest(p, None)
                        .is_none_or(|hit| !hit.is_inside() && hit.distance >= self.margin)
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::closest::TargetSource;
    use crate::mesh::primitives::MeshGenerator;

    fn bone(center: Vec3, radii: Vec3) -> TargetSurface {
        let generator = MeshGenerator::Ellipsoid {
            center,
            radii,
            segments: 32,
            stacks: 24,
        };
        let m = generator.build("bone").unwrap();
        TargetSurface::new(
            "bone",
            TargetSource::Bone(0),
            m.positions.clone(),
            m.triangles.clone(),
        )
    }

    fn ball(center: Vec3, radius: f32) -> TargetSurface {
        bone(center, Vec3::splat(radius))
    }

    #[test]
    fn a_ring_through_a_bone_moves_out_within_its_plane() {
        let bone = ball(Vec3::ZERO, 0.02);
        let normal = Vec3::Z;
        let (c, r) = clear_ring(
            Vec3::new(0.005, 0.0, 0.0),
            normal,
            0.01,
            0.0025,
            Vec3::ZERO,
            0.001,
            &[&bone],
        );
        assert_eq!(r, 0.01);
        // In the plane z = 0, beyond the ball's radius plus the ring's.
        assert!(c.z.abs() < 1e-6, "left its plane: {c}");
        assert!(c.length() >= 0.03 + 0.0009, "still in the bone: {c}");
        assert!(c.x > 0.0, "went the long way round: {c}");
    }

    #[test]
    fn a_clear_ring_stays() {
        let bone = ball(Vec3::ZERO, 0.02);
        let start = Vec3::new(0.05, 0.0, 0.0);
        assert_eq!(
            clear_ring(start, Vec3::Z, 0.01, 0.0025, Vec3::ZERO, 0.001, &[&bone]),
            (start, 0.01)
        );
    }

    #[test]
    fn a_ring_between_two_bones_thins_to_pass() {
        // A 12 mm gap between two long bones along z: a 10 mm ring in the
        // plane y = 0 (20 mm wide) cannot pass between them, a 5 mm one can.
        let long = Vec3::new(0.02, 0.02, 0.3);
        let a = bone(Vec3::new(-0.026, 0.0, 0.0), long);
        let b = bone(Vec3::new(0.026, 0.0, 0.0), long);
        let (c, r) = clear_ring(
            Vec3::ZERO,
            Vec3::Y,
            0.01,
            0.0025,
            Vec3::ZERO,
            0.0005,
            &[&a, &b],
        );
        assert!((0.0025..0.01).contains(&r), "radius {r}");
        assert!(c.y.abs() < 1e-6, "left its plane: {c}");
        for bone in [&a, &b] {
            assert!(!bone.contains(c));
        }
    }
}
