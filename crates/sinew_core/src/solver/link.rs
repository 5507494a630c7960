//! Target connections: one Sliding, Soft and Hard constraint per surface
//! vertex (SPEC §5.7–5.9, the thesis' counts), and which of them hold.
//!
//! ```text
//! Sliding (contact)   the nearest target within contact_reach at rest
//! Soft, Hard (tie)    the nearest bone at any gap, or a muscle within reach
//! muscles             only where the vertex and its one-ring lie outside
//!                     the other muscle at rest
//! ```
//!
//! A connection with no such target is made to the nearest target all the
//! same and switched off (infinite compliance), so the counts stay the
//! thesis'. Why each rule (measured with `sinew check`; see ARCHITECTURE.md,
//! "Connections"):
//!
//! - *Sliding is contact.* A vertex centimetres from a bone keeps that gap
//!   over the bone's distance field, whose closest point jumps across the
//!   bone's medial axis; T5 with Sliding on bones at any gap never settled.
//! - *Ties to a muscle are short.* A Hard goal sits in the frame of a small
//!   triangle of the other muscle, so the goal moves by the lever arm times
//!   that triangle's every rotation, and the other muscle's goals follow
//!   this one's: P3, tied at up to 5 cm, crumpled into shards.
//! - *No ties across a seam.* Imported muscles overlap (CORB has 118 of 162
//!   vertices inside DELT2): a vertex inside another muscle, or next to where
//!   the two surfaces cross, cannot keep a gap both muscles agree on.

use super::workspace::{BoneCell, MuscleWorkspace};
use crate::closest::{ClosestHit, NO_TRIANGLE, SideMemo, TargetSet, TargetSource};
use crate::constraints::{ParticleId, SlidingContact, TargetSlot};
use crate::muscle::{Muscle, SurfaceAnchor};
use glam::Vec3;

/// A target slot and the closest point on it.
type Candidate = (usize, ClosestHit);

/// Creates one Sliding, Soft and Hard constraint per surface vertex of `m`
/// against its targets (`ws.target_ids` index `targets`), from the current
/// positions (module docs), and resets the workspace's closest-data caches.
pub fn link<T: TargetSet + ?Sized>(m: &mut Muscle, ws: &mut MuscleWorkspace, targets: &T) {
    let nt = ws.target_ids.len();
    let n = m.surface_count;
    let reach = m.contact_reach();
    let c = &mut m.constraints;
    c.sliding = Default::default();
    c.soft = Default::default();
    c.hard = Default::default();
    c.soft_anchor.clear();
    c.hard_anchor.clear();
    if nt == 0 {
        m.relink_weights();
        ws.reset_caches(m);
        return;
    }
    let surfaces: Vec<_> = ws.target_ids.iter().map(|&t| targets.target(t)).collect();
    c.sliding.targets = nt;
    c.sliding.mode = m.params.sliding_mode;
    c.sliding.walk_first_only = m.params.is_surface_layer()
        && m.params.sliding_mode == crate::constraints::SlidingMode::Contact;
    // A contact layer reads which side of a bone it is on from the bone's
    // features ([`TargetSurface::settle_side`]); muscles keep the smooth
    // normal's reading (cheaper, and their figures were measured with it).
    let layer = c.sliding.walk_first_only;
    c.sliding.rigid = surfaces
        .iter()
        .map(|t| !t.is_deforming() && matches!(t.source, TargetSource::Bone(_)))
        .collect();
    // Closest points at rest per (vertex, target), searched only where they
    // can matter — a skin vertex has every muscle and bone of a body as a
    // target and a handful near it: every target whose box is within reach
    // (a contact) and, nearest box first, any that may still be the
    // nearest target or the nearest rigid one (the tie at any gap). One
    // left out is outside its box, so outside it, and farther than those:
    // `None`, as a target out of reach.
    let mut hits: Vec<Option<ClosestHit>> = vec![None; n * nt];
    let mut order: Vec<(f32, usize)> = Vec::with_capacity(nt);
    for v in 0..n {
        let q = m.x[v];
        order.clear();
        order.extend(
            surfaces
                .iter()
                .enumerate()
                .map(|(s, t)| (t.lower_bound(q), s)),
        );
        order.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (mut nearest, mut nearest_rigid) = (f32::INFINITY, f32::INFINITY);
        for &(lower, slot) in &order {
            let rigid = !surfaces[slot].is_deforming();
            if lower > reach && lower > nearest {
                if lower > nearest_rigid {
                    break; // every later box is farther still
                }
                if !rigid {
                    continue;
                }
            }
            let hit = surfaces[slot].closest(q, None).map(|hit| {
                if layer {
                    surfaces[slot].settle_side(q, hit, &mut SideMemo::default(), slot as u32)
                } else {
                    hit
                }
            });
            if let Some(h) = hit {
                nearest = nearest.min(h.distance);
                if rigid {
                    nearest_rigid = nearest_rigid.min(h.distance);
                }
            }
            hits[v * nt + slot] = hit;
        }
    }
    // Whether vertex `v` may touch target `slot`: within reach, and for a
    // muscle, outside it at rest with every neighbour.
    let outside = |v: usize, slot: usize| hits[v * nt + slot].is_none_or(|h| !h.is_inside());
    let touches = |v: usize, slot: usize| {
        let within = hits[v * nt + slot].is_some_and(|h| h.distance <= reach);
        within
            && (!surfaces[slot].is_deforming()
                || outside(v, slot)
                    && m.mesh
                        .neighbors_of(v)
                        .iter()
                        .all(|&u| outside(u as usize, slot)))
    };
    let thickness = m.maps.thickness.as_deref();
    // Rest gaps and sides per (vertex, target), dense while linking; the
    // batch keeps them sparse (`SlidingBatch::set_rest`).
    let mut rest_gap: Vec<f32> = Vec::with_capacity(n * nt);
    let mut rest_outside: Vec<bool> = Vec::with_capacity(n * nt);
    for v in 0..n {
        let q = m.x[v];
        let mut nearest: Option<Candidate> = None;
        let mut contact: Option<Candidate> = None;
        let mut tie: Option<Candidate> = None;
        for (slot, surface) in surfaces.iter().enumerate() {
            let cell = v * nt + slot;
            let Some(h) = hits[cell] else {
                rest_gap.push(f32::INFINITY);
                rest_outside.push(true);
                continue;
            };
            let touching = touches(v, slot);
            // Sliding never chooses a target out of its band (see
            // `SlidingBatch::candidate_gap`); the thickness map caps the gap.
            let gap = thickness.map_or(h.distance, |t| h.distance.min(t[v]));
            rest_gap.push(if touching { gap } else { f32::INFINITY });
            rest_outside.push(!h.is_inside());
            let candidate = Some((slot, h));
            let nearer =
                |best: &Option<Candidate>| best.is_none_or(|(_, b)| h.distance < b.distance);
            if nearer(&nearest) {
                nearest = candidate;
            }
            if touching && nearer(&contact) {
                contact = candidate;
            }
            if (touching || !surface.is_deforming()) && nearer(&tie) {
                tie = candidate;
            }
        }
        let Some(nearest) = nearest else {
            continue;
        };
        let (slot, hit) = contact.unwrap_or(nearest);
        let target = surfaces[slot];
        let s = &mut c.sliding;
        s.particle.push(ParticleId::from_index(v));
        s.connected.push(contact.is_some());
        s.compliance.push(0.0);
        s.contact.push(SlidingContact {
            point: hit.point.into(),
            normal: hit.normal.into(),
            barycentric: hit.barycentric.into(),
            target_w: target.point_inverse_mass(hit.triangle, hit.barycentric.into()),
            gap: f32::INFINITY,
            triangle: hit.triangle,
            target: TargetSlot::new(slot),
            outside: true,
        });
        s.plane.push(target.face_normal(hit.triangle));
        s.lambda.push(0.0);
        let (slot, hit) = tie.unwrap_or(nearest);
        let target = surfaces[slot];
        let anchor = SurfaceAnchor {
            target: TargetSlot::new(slot),
            triangle: hit.triangle,
            barycentric: hit.barycentric.into(),
            local: Vec3::ZERO,
            connected: tie.is_some(),
        };
        let target_w = target.point_inverse_mass(hit.triangle, hit.barycentric.into());
        c.soft.push(
            ParticleId::from_index(v),
            hit.point.into(),
            hit.distance,
            0.0,
        );
        c.soft_anchor.push(anchor);
        let frame = target.frame_at(hit.triangle, hit.barycentric.into());
        let local = Vec3::from(frame.basis.transpose() * glam::Vec3A::from(q - frame.origin));
        c.hard.push(ParticleId::from_index(v), q, 0.0, 0.0);
        c.hard_anchor.push(SurfaceAnchor { local, ..anchor });
        if let (Some(s), Some(h)) = (c.soft.target_w.last_mut(), c.hard.target_w.last_mut()) {
            (*s, *h) = (target_w, target_w);
        }
    }
    // The rows were pushed for every vertex; keep those of the constraints
    // (vertices without any hit have no constraint).
    if c.sliding.len() != n {
        let keep: Vec<usize> = c.sliding.particle.iter().map(|&v| v.index()).collect();
        rest_gap = keep_rows(&rest_gap, &keep, nt);
        rest_outside = keep_rows(&rest_outside, &keep, nt);
    }
    c.sliding.set_rest(&rest_gap, &rest_outside);
    for i in 0..c.sliding.len() {
        c.sliding.choose(i, c.sliding.contact[i].target.get());
    }
    m.relink_weights();
    ws.reset_caches(m);
    // The walks start from the closest triangles at rest: closest data's
    // on each candidate, bone contacts' on the nearest bones hit.
    let s = &m.constraints.sliding;
    let mut bones: Vec<(f32, usize, u32)> = Vec::new();
    for (i, v) in s.particle.iter().enumerate() {
        let row = &hits[v.index() * nt..(v.index() + 1) * nt];
        for k in s.candidate_start[i] as usize..s.candidate_start[i + 1] as usize {
            let hit = row[s.candidates[k] as usize];
            ws.candidate_warm[k] = hit.map_or(NO_TRIANGLE, |h| h.triangle);
        }
        bones.clear();
        bones.extend(row.iter().enumerate().filter_map(|(slot, hit)| {
            let h = hit.filter(|_| s.rigid[slot])?;
            Some((h.distance, slot, h.triangle))
        }));
        bones.sort_by(|a, b| a.0.total_cmp(&b.0));
        let ways = ws.bone_ways;
        for (cell, &(_, slot, triangle)) in ws.bone_cells[i * ways..(i + 1) * ways]
            .iter_mut()
            .zip(&bones)
        {
            *cell = BoneCell {
                slot: slot as u32,
                warm: triangle,
                clearance: glam::Vec4::ZERO,
            };
        }
    }
}

/// The rows `keep` of `all` (rows of `width` cells), in that order.
fn keep_rows<T: Copy>(all: &[T], keep: &[usize], width: usize) -> Vec<T> {
    keep.iter()
        .flat_map(|&row| &all[row * width..(row + 1) * width])
        .copied()
        .collect()
}
