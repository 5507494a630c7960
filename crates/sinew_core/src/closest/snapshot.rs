//! A deforming target's snapshot: the positions, normals, BVH fit and
//! inverse masses other muscles read of a muscle, as its driver publishes
//! them (a copy each iteration, or a swap of a buffer the muscle staged in
//! its own task) and refreshes them once a frame. A deforming target's
//! geometry is its own (copied on its first write after a clone), so these
//! writes never reach another target.

use super::TargetSurface;
use glam::Vec3;
use std::sync::Arc;

impl TargetSurface {
    /// Sets the inverse masses of a deforming target's vertices (its
    /// muscle's particles), for [`TargetSurface::point_inverse_mass`].
    pub fn set_inverse_masses(&mut self, inverse_mass: &[f32]) {
        self.inverse_mass.clear();
        self.inverse_mass.extend_from_slice(inverse_mass);
    }

    /// Replaces the positions of a deforming target (same topology). This is
    /// the per-iteration snapshot publish. The BVH keeps its boxes; the
    /// largest displacement since they were fitted (the slack) makes the full
    /// search conservative until [`TargetSurface::refit`] refits them. Normals
    /// keep their values until [`TargetSurface::update_normals`]. Positions
    /// that are not all finite (a muscle blowing up) are not published: the
    /// muscles sliding on it keep its last finite surface, and the run-time
    /// guard ([`crate::solver::guard()`]) puts the muscle back.
    pub fn publish(&mut self, positions: &[Vec3]) {
        let moved = self.moved_squared(positions);
        if !moved.is_finite() {
            return;
        }
        let g = Arc::make_mut(&mut self.geometry);
        g.positions.clear();
        g.positions.extend_from_slice(positions);
        self.slack = moved.sqrt();
    }

    /// The largest squared distance of `positions` from those the BVH was
    /// fitted to (the slack squared), NaN or infinite when a position is
    /// not finite: one pass with a NaN-propagating maximum, kept in four
    /// lanes (every fourth position each) so that four compare-and-select
    /// chains run side by side instead of one; a maximum does not depend
    /// on the order it is taken in, so the result is the one-lane pass's.
    pub fn moved_squared(&self, positions: &[Vec3]) -> f32 {
        let fitted = &self.geometry.fitted[..positions.len().min(self.geometry.fitted.len())];
        let (p4, f4) = (
            positions[..fitted.len()].chunks_exact(4),
            fitted.chunks_exact(4),
        );
        let tail = p4.remainder().iter().zip(f4.remainder());
        let mut lanes = [0.0f32; 4];
        for (p, f) in p4.zip(f4) {
            for j in 0..4 {
                lanes[j] = nan_max(lanes[j], p[j].distance_squared(f[j]));
            }
        }
        for (lane, (p, f)) in lanes.iter_mut().zip(tail) {
            *lane = nan_max(*lane, p.distance_squared(*f));
        }
        lanes.into_iter().fold(0.0, nan_max)
    }

    /// [`TargetSurface::publish`] of positions staged beforehand, with
    /// their [`TargetSurface::moved_squared`]: the staged buffer and the
    /// snapshot's swap (no copy), the same snapshot and slack as
    /// publishing the positions. Nothing when they are not finite (the
    /// buffer keeps them).
    pub fn publish_staged(&mut self, positions: &mut Vec<Vec3>, moved_squared: f32) {
        debug_assert_eq!(
            positions.len(),
            self.geometry.positions.len(),
            "staged for another surface"
        );
        if !moved_squared.is_finite() {
            return;
        }
        std::mem::swap(&mut Arc::make_mut(&mut self.geometry).positions, positions);
        self.slack = moved_squared.sqrt();
    }

    /// Recomputes the vertex normals from the current positions. The solver
    /// does it in the first iteration of each frame; within a frame the
    /// normals of a muscle target lag its positions by a few iterations.
    pub fn update_normals(&mut self) {
        let g = Arc::make_mut(&mut self.geometry);
        crate::mesh::vertex_normals(&g.triangles, &g.positions, &mut g.normals);
    }

    /// Refits the BVH to the current positions once the slack exceeds a
    /// quarter of the mean edge length (or always, with `force`).
    pub fn refit(&mut self, force: bool) {
        if !force && self.slack <= self.geometry.max_slack {
            return;
        }
        let g = Arc::make_mut(&mut self.geometry);
        g.bvh.refit(&g.positions, &g.triangles);
        g.fitted.clone_from(&g.positions);
        self.slack = 0.0;
    }
}

/// The larger of `m` and `d`, or NaN where either is.
#[inline(always)]
fn nan_max(m: f32, d: f32) -> f32 {
    if d > m || d.is_nan() { d } else { m }
}
