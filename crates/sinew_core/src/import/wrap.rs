//! A tendon's path around a wrapping geom (MJCF `<spatial><geom geom
//! sidesite>`): the shortest path from one point to the next that does not
//! enter a sphere or an (infinite) cylinder, on the side of the side site
//! where one is named, as MuJoCo wraps its tendons.
//!
//! ```text
//! sphere     in the plane through its centre and the two points
//! cylinder   in the plane across its axis; the height along the axis grows
//!            in proportion to the length travelled in that plane (a helix
//!            on the surface)
//! in 2-D     a circle of radius r about the origin, points a and b outside
//!            it: the path runs from a along a tangent to the circle, around
//!            it, and along a tangent to b:
//!              a's tangent point at angle θ_a ± acos(r/|a|), b's at θ_b ∓ acos(r/|b|)
//!            taken around the side of the side site (without one, the shorter way);
//!            it wraps when the straight segment a–b cuts the circle, or
//!            passes it on the side away from the side site
//! ```
//!
//! A point inside the geom, or a geom too small to matter, leaves the
//! straight segment (as MuJoCo does). The arc is returned as points every
//! [`ARC_STEP`] radians, for the muscle builder's spline to run through.

use super::mjcf::{MjSite, MjTendon, MjcfModel, WrapShape};
use crate::error::ImportError;
use glam::{Affine3A, Quat, Vec2, Vec3};
use std::f32::consts::{PI, TAU};

/// Angle between two samples of a wrapped arc. Units: rad.
pub const ARC_STEP: f32 = PI / 12.0;

/// Wrap points nearer than this to the point before them or to the next
/// site are left out of a path: the builder rejects shorter segments.
/// Units: m.
pub const SAME_POINT: f32 = super::builder::MIN_SEGMENT;

/// The path in the world (bodies at `frame_of`) of `tendon`, whose sites
/// are `sites` (resolved: [`MjcfModel::tendon_sites`]): its sites, and
/// where `wrap` is set, the points where it wraps each of its wrapping
/// geoms between them.
pub(super) fn tendon_path(
    model: &MjcfModel,
    tendon: &MjTendon,
    sites: &[&MjSite],
    frame_of: &impl Fn(Option<usize>) -> Affine3A,
    wrap: bool,
) -> Result<Vec<Vec3>, ImportError> {
    let at = |s: &MjSite| frame_of(s.body).transform_point3(s.pos);
    let mut points = Vec::with_capacity(sites.len());
    for (k, site) in sites.iter().enumerate() {
        let next = at(site);
        if wrap && k > 0 {
            for w in tendon.wraps.iter().filter(|w| w.after == k) {
                let unknown = |kind: &'static str, name: &str| {
                    w.origin.error(
                        kind,
                        format!(
                            "tendon '{}' wraps around {kind} '{name}', which does not exist",
                            tendon.name
                        ),
                    )
                };
                let geom = model
                    .wrap_geom(&w.geom)
                    .ok_or_else(|| unknown("geom", &w.geom))?;
                let (WrapShape::Sphere { radius } | WrapShape::Cylinder { radius }) = geom.shape;
                if !(radius.is_finite() && radius > 0.0) {
                    return Err(w.origin.error(
                        "geom",
                        format!(
                            "tendon '{}' wraps around geom '{}', whose radius (size) is {radius}: it must be positive",
                            tendon.name, w.geom
                        ),
                    ));
                }
                let side = match &w.sidesite {
                    Some(name) => {
                        let i = model
                            .site_index(name)
                            .ok_or_else(|| unknown("site", name))?;
                        Some(at(&model.sites[i]))
                    }
                    None => None,
                };
                let placed =
                    frame_of(geom.body) * Affine3A::from_rotation_translation(geom.quat, geom.pos);
                let (_, rotation, centre) = placed.to_scale_rotation_translation();
                let from = *points.last().expect("a site precedes every wrap");
                let arc = wrap_path(from, next, geom.shape, centre, rotation, side);
                push_apart(&mut points, arc, next);
            }
        }
        points.push(next);
    }
    Ok(points)
}

/// Appends the wrap points `arc` to `points` (not empty), leaving out any
/// within [`SAME_POINT`] of the point before it or of the next site
/// `next`: a site on (or just off) its geom is its own tangent point.
fn push_apart(points: &mut Vec<Vec3>, arc: Vec<Vec3>, next: Vec3) {
    for p in arc {
        let last = *points.last().expect("a site precedes every wrap");
        if p.distance(last) > SAME_POINT && p.distance(next) > SAME_POINT {
            points.push(p);
        }
    }
}

/// The points between `a` and `b` (world) where the path wraps `shape`
/// centred at `centre` and turned by `rotation` (a cylinder's axis is its
/// local Z), on the side of `side` (world) if given: the tangent points and
/// the arc between them, empty where the straight segment stays clear.
pub fn wrap_path(
    a: Vec3,
    b: Vec3,
    shape: WrapShape,
    centre: Vec3,
    rotation: Quat,
    side: Option<Vec3>,
) -> Vec<Vec3> {
    let to_local = |p: Vec3| rotation.inverse() * (p - centre);
    let (la, lb) = (to_local(a), to_local(b));
    let ls = side.map(to_local);
    match shape {
        WrapShape::Sphere { radius } => {
            // The plane through the centre and both points (or the side
            // site, where the three lie on one line).
            let normal = la
                .cross(lb)
                .try_normalize()
                .or_else(|| ls.and_then(|s| la.cross(s).try_normalize()))
                .unwrap_or_else(|| la.any_orthonormal_vector());
            let Some(e1) = la.try_normalize() else {
                return Vec::new();
            };
            let e2 = normal.cross(e1);
            let flat = |p: Vec3| Vec2::new(p.dot(e1), p.dot(e2));
            let side2 = ls.map(flat);
            circle_wrap(flat(la), flat(lb), radius, side2)
                .into_iter()
                .map(|p| centre + rotation * (e1 * p.x + e2 * p.y))
                .collect()
        }
        WrapShape::Cylinder { radius } => {
            let flat = |p: Vec3| Vec2::new(p.x, p.y);
            let arc = circle_wrap(flat(la), flat(lb), radius, ls.map(flat));
            if arc.is_empty() {
                return Vec::new();
            }
            // Heights in proportion to the length travelled across the axis.
            let mut travelled = vec![flat(la).distance(arc[0])];
            for w in arc.windows(2) {
                travelled.push(travelled.last().unwrap() + w[0].distance(w[1]));
            }
            let total = travelled.last().unwrap() + arc.last().unwrap().distance(flat(lb));
            arc.iter()
                .zip(&travelled)
                .map(|(p, s)| {
                    let z = la.z + (lb.z - la.z) * s / total.max(f32::MIN_POSITIVE);
                    centre + rotation * Vec3::new(p.x, p.y, z)
                })
                .collect()
        }
    }
}

/// The 2-D wrap (see the module): the tangent points and the arc between
/// them, from `a`'s side to `b`'s, or nothing.
fn circle_wrap(a: Vec2, b: Vec2, radius: f32, side: Option<Vec2>) -> Vec<Vec2> {
    let (da, db) = (a.length(), b.length());
    if radius <= 0.0 || da <= radius || db <= radius {
        return Vec::new();
    }
    // Which way round: +1 counter-clockwise from a to b, −1 clockwise.
    let around = |turn: f32| {
        let (ta, tb) = (a.y.atan2(a.x), b.y.atan2(b.x));
        let (aa, ab) = ((radius / da).acos(), (radius / db).acos());
        let start = ta + turn * aa;
        let end = tb - turn * ab;
        let sweep = (turn * (end - start)).rem_euclid(TAU);
        let length = (da * da - radius * radius).sqrt()
            + (db * db - radius * radius).sqrt()
            + radius * sweep;
        (start, sweep, length)
    };
    let (ccw, cw) = (around(1.0), around(-1.0));
    let d = b - a;
    // Counter-clockwise from a to b, the circle lies to the path's left:
    // the path passes it on the right of a → b.
    let turn = match side {
        Some(s) if s.dot(Vec2::new(d.y, -d.x)) > 0.0 => 1.0,
        Some(_) => -1.0,
        None if ccw.2 <= cw.2 => 1.0,
        None => -1.0,
    };
    // Whether the straight segment cuts the circle, and on which side it
    // passes it.
    let t = (-a.dot(d) / d.length_squared().max(f32::MIN_POSITIVE)).clamp(0.0, 1.0);
    let nearest = a + d * t;
    let cuts = nearest.length() < radius;
    let wrong_side = side.is_some_and(|s| nearest.dot(s) < 0.0);
    if !cuts && !wrong_side {
        return Vec::new();
    }
    let (start, sweep, _) = if turn > 0.0 { ccw } else { cw };
    let steps = (sweep / ARC_STEP).ceil().max(1.0) as usize;
    (0..=steps)
        .map(|k| {
            let angle = start + turn * sweep * k as f32 / steps as f32;
            Vec2::new(angle.cos(), angle.sin()) * radius
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const SPHERE: WrapShape = WrapShape::Sphere { radius: 1.0 };

    /// Length of the polyline a → points → b.
    fn length(a: Vec3, points: &[Vec3], b: Vec3) -> f32 {
        let mut all = vec![a];
        all.extend_from_slice(points);
        all.push(b);
        all.windows(2).map(|w| w[0].distance(w[1])).sum()
    }

    #[test]
    fn a_segment_clear_of_the_sphere_does_not_wrap() {
        let (a, b) = (Vec3::new(-2.0, 1.5, 0.0), Vec3::new(2.0, 1.5, 0.0));
        assert!(wrap_path(a, b, SPHERE, Vec3::ZERO, Quat::IDENTITY, None).is_empty());
    }

    #[test]
    fn a_segment_through_the_sphere_goes_round_it_along_the_great_circle() {
        // From (−2, 0, 0) to (2, 0, 0), the side site above (+Y): the
        // tangents from each point touch at 60° from the axis, the arc
        // between spans 60°, the whole path 2√3 + π/3.
        let (a, b) = (Vec3::new(-2.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0));
        let side = Some(Vec3::new(0.0, 3.0, 0.0));
        let path = wrap_path(a, b, SPHERE, Vec3::ZERO, Quat::IDENTITY, side);
        assert!(path.len() >= 2);
        for p in &path {
            assert!((p.length() - 1.0).abs() < 1e-5, "{p}");
            assert!(p.y > 0.0 && p.z.abs() < 1e-5, "{p}");
        }
        let expected = 2.0 * 3f32.sqrt() + PI / 3.0;
        assert!(
            (length(a, &path, b) - expected).abs() < 1e-2,
            "{}",
            length(a, &path, b)
        );
        // The other side with the side site below.
        let below = wrap_path(a, b, SPHERE, Vec3::ZERO, Quat::IDENTITY, Some(-Vec3::Y));
        assert!(below.iter().all(|p| p.y < 0.0));
    }

    #[test]
    fn a_side_site_makes_a_clear_segment_on_the_other_side_wrap() {
        // The segment passes below the sphere; the side site is above.
        let (a, b) = (Vec3::new(-2.0, -1.2, 0.0), Vec3::new(2.0, -1.2, 0.0));
        assert!(wrap_path(a, b, SPHERE, Vec3::ZERO, Quat::IDENTITY, Some(-Vec3::Y)).is_empty());
        let over = wrap_path(a, b, SPHERE, Vec3::ZERO, Quat::IDENTITY, Some(Vec3::Y));
        assert!(!over.is_empty() && over.iter().all(|p| p.y > -1e-4));
    }

    #[test]
    fn a_cylinder_is_wrapped_as_a_helix_across_its_axis() {
        // Axis along world X (local Z turned onto X); points on either
        // side of it, at different heights along it.
        let rotation = Quat::from_rotation_y(PI / 2.0);
        let shape = WrapShape::Cylinder { radius: 0.5 };
        let (a, b) = (Vec3::new(0.0, -2.0, 0.0), Vec3::new(1.0, 2.0, 0.0));
        let path = wrap_path(a, b, shape, Vec3::ZERO, rotation, Some(Vec3::Z));
        assert!(path.len() >= 2);
        let mut last_x = a.x;
        for p in &path {
            // On the surface (distance 0.5 from the X axis), on the +Z side,
            // climbing steadily along the axis.
            assert!((Vec2::new(p.y, p.z).length() - 0.5).abs() < 1e-5, "{p}");
            assert!(p.z > -1e-5, "{p}");
            assert!(p.x >= last_x - 1e-6 && p.x <= b.x, "{p}");
            last_x = p.x;
        }
    }

    #[test]
    fn wrap_points_on_a_site_are_left_out() {
        let (a, b) = (Vec3::ZERO, Vec3::X);
        let mut points = vec![a];
        let arc = vec![
            a + Vec3::splat(1e-6),
            Vec3::new(0.5, 0.2, 0.0),
            b - Vec3::splat(1e-6),
        ];
        push_apart(&mut points, arc, b);
        assert_eq!(points, vec![a, Vec3::new(0.5, 0.2, 0.0)]);
    }

    #[test]
    fn a_point_inside_the_geom_leaves_the_straight_segment() {
        let (a, b) = (Vec3::new(0.5, 0.0, 0.0), Vec3::new(3.0, 0.0, 0.0));
        assert!(wrap_path(a, b, SPHERE, Vec3::ZERO, Quat::IDENTITY, None).is_empty());
    }
}
