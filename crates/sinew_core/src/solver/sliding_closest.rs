//! Closest data's Sliding part (BE5, SPEC §6): for each vertex in a
//! contact band, the target that claims it and the closest point on it.
//! The loop asks for each vertex's chain of loads a few steps ahead of its
//! work ([`crate::prefetch`]); [`super::closest_data`] runs it, on pieces
//! of the batch in parallel.

use super::params::ClosestSchedule;
use super::sliding_run::SlidingRun;
use super::workspace::BoneCell;
use crate::closest::{ClosestHit, NO_TRIANGLE, TargetSet};
use crate::constraints::{SlidingContact, TargetId, TargetSlot};
use crate::prefetch::prefetch;
use glam::Vec3;

/// How strongly a target claims a vertex's Sliding constraint. A bone the
/// vertex is inside of claims it first (the deepest first), so Sliding
/// pushes it out even when a muscle is nearer; then the target the vertex
/// has come nearest to *relative to its rest gap* (`distance − rest gap`):
/// at rest every target's claim is 0 and the vertex keeps the one it
/// rests on. Ranking by distance alone switched a vertex between targets
/// with different rest gaps as it sagged, a jump in its constraint every
/// `choose_interval` frames (the tip of T5's medial triceps held a 4-frame
/// limit cycle).
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd)]
enum Claim {
    /// Inside a bone: minus the depth.
    InsideBone(f32),
    /// Outside: distance − rest gap.
    Gap(f32),
}

impl Claim {
    /// Whether this claim takes the vertex from `held`: a deeper bone, any
    /// bone over a gap, or a gap smaller by more than a tenth of the
    /// contact band (so that near-ties keep the target the vertex has).
    fn beats(&self, held: &Claim, reach: f32) -> bool {
        match (*self, *held) {
            (Claim::Gap(a), Claim::Gap(b)) => a < b - 0.1 * reach,
            (a, b) => a < b,
        }
    }
}

/// What the Sliding part of closest data reads.
pub(super) struct SlidingInput<'a, T: ?Sized> {
    pub(super) p: &'a [Vec3],
    pub(super) target_ids: &'a [TargetId],
    pub(super) targets: &'a T,
    pub(super) search: ClosestSchedule,
    /// The muscle's contact reach: a target farther than this at rest is
    /// never chosen.
    pub(super) reach: f32,
    /// A contact layer's nearest point on a bone is only ever walked to,
    /// never searched for anew once known (see [`crate::constraints::SlidingBatch::walk_first_only`]).
    pub(super) walk_on_bones: bool,
}

impl<T: TargetSet + ?Sized> SlidingInput<'_, T> {
    /// Closest points for a run of Sliding constraints.
    pub(super) fn closest(&self, run: SlidingRun) {
        let SlidingRun {
            particle,
            connected,
            first: run_start,
            contact,
            plane,
            warm,
            bone_cells,
            bone_ways,
            rigid,
            side_memo,
            candidate_start,
            candidates,
            candidate_gap,
            candidate_outside,
        } = run;
        let (nt, search) = (self.target_ids.len(), self.search);
        let at = |k: u32| k as usize - run_start;
        // Where the run's candidates start in the batch's: a candidate's
        // warm cell is its index in the run's `warm` from there.
        let base = candidate_start[0] as usize;
        // The surface a contact was last found on.
        let held_surface = |c: &SlidingContact| {
            let slot = c.target.get().filter(|&s| s < nt)?;
            Some(self.targets.target(self.target_ids[slot]))
        };
        // The loop runs `LEAD` steps ahead of the work: step `n` asks for
        // the loads of vertex `n` (its index, contact, bone cells and where
        // its candidates start), then of vertex `n − 1` (its position, its
        // candidates and its triangle's corner indices), then of vertex
        // `n − 2` (the corners' positions, normals and inverse masses),
        // each link of a chain a step after the one it needs (by then in
        // the cache), and works on vertex `n − 3`. The first steps only ask.
        const LEAD: usize = 3;
        let lagging = |n: usize, by: usize| n.checked_sub(by).and_then(|m| connected.get(m));
        for n in 0..connected.len() + LEAD {
            if let Some(&ahead) = lagging(n, 0) {
                let i = at(ahead);
                prefetch(&particle[i]);
                prefetch(&contact[i]);
                prefetch(&candidate_start[i]);
                if let Some(cell) = bone_cells.get(i * bone_ways) {
                    prefetch(cell);
                }
            }
            if let Some(&ahead) = lagging(n, 1) {
                let i = at(ahead);
                prefetch(&self.p[particle[i].index()]);
                let from = candidate_start[i] as usize;
                if let Some(slot) = candidates.get(from) {
                    prefetch(slot);
                    prefetch(&candidate_gap[from]);
                    prefetch(&candidate_outside[from]);
                }
                if let Some(cell) = warm.get(from - base) {
                    prefetch(cell);
                }
                if let Some(surface) = held_surface(&contact[i]) {
                    surface.prefetch_triangle(contact[i].triangle);
                }
            }
            if let Some(&next) = lagging(n, 2) {
                let i = at(next);
                if let Some(surface) = held_surface(&contact[i]) {
                    surface.prefetch_corners(contact[i].triangle);
                }
            }
            let Some(&k) = lagging(n, LEAD) else {
                continue;
            };
            let i = at(k);
            let v = particle[i].index();
            let q = self.p[v];
            let held_contact = contact[i];
            let first = held_contact.target.get().unwrap_or(usize::MAX);
            let choose = search.chooses(v) || first >= nt;
            // Later iterations project the vertex onto the feature (face
            // plane, edge or corner) of the triangle the walk found: the
            // closest point while the vertex stays in that feature's region.
            if !choose && !search.walk && search.feature_contacts {
                let surface = self.targets.target(self.target_ids[first]);
                let (t, bary) = (held_contact.triangle, held_contact.barycentric);
                contact[i].point = surface.on_feature(q, t, bary, plane[i]);
                continue;
            }
            // Last iteration's target first. The vertex re-chooses in the
            // first iteration of one frame in `choose_interval` (staggered
            // over vertices); in between it keeps its target but, in the
            // first iteration of a frame, still checks every bone whose box
            // it is in (it may have entered one).
            let bones_only = !choose;
            let rescan = choose || search.first_of_frame;
            // A bone held in an iteration that visits no other target is
            // the only candidate, with the rest gap and side stored when it
            // was chosen (a finite gap: it is a candidate): the candidate
            // lists, a few cache lines per vertex, are not read.
            let (held_gap, held_outside) = (held_contact.gap, held_contact.outside);
            let held_bone = (!rescan && first < nt && rigid[first] && held_gap.is_finite())
                .then_some((first, held_gap, held_outside, usize::MAX));
            // `(slot, rest gap, outside at rest, warm cell)` of each
            // candidate (its warm cell in the run's `warm`).
            let run = match held_bone {
                Some(_) => base..base,
                None => candidate_start[i] as usize..candidate_start[i + 1] as usize,
            };
            let within = candidates[run.clone()].iter().map(|&s| s as usize);
            let within = within
                .zip(candidate_gap[run.clone()].iter().copied())
                .zip(candidate_outside[run.clone()].iter().copied())
                .zip(run.start - base..run.end - base)
                .map(|(((slot, gap), out), cell)| (slot, gap, out, cell));
            // The held target's entry; out of its contact band it has none
            // (no gap to keep) and is not held.
            let held = held_bone.or_else(|| {
                (first < nt)
                    .then(|| within.clone().find(|&(s, ..)| s == first))
                    .flatten()
            });
            let others = rescan.then_some(within);
            let others = others.into_iter().flatten().filter(|&(s, ..)| s != first);
            let full = search.wants(v);
            let mut best: Option<(Claim, ClosestHit, usize, f32, bool)> = None;
            for (slot, gap, rest_outside, cell) in held.into_iter().chain(others) {
                let surface = self.targets.target(self.target_ids[slot]);
                // A target out of the vertex's contact band at rest (or
                // across a seam, see `link_muscle`) is never chosen.
                if gap > self.reach || bones_only && slot != first && surface.is_deforming() {
                    continue;
                }
                // Only a hit nearer than `bound` can claim the vertex.
                let bound = match &best {
                    None => f32::MAX,
                    Some((claim, ..)) => {
                        let lower = surface.lower_bound(q);
                        // Inside a bone's box the vertex may be inside the
                        // bone, which claims it whatever the others do.
                        if lower == 0.0 && !surface.is_deforming() {
                            f32::MAX
                        } else {
                            match *claim {
                                Claim::InsideBone(_) => continue,
                                Claim::Gap(g) if lower >= g + gap => continue,
                                Claim::Gap(g) => g + gap,
                            }
                        }
                    }
                };
                let cell = match rigid[slot] {
                    false => &mut warm[cell],
                    true => {
                        let ways = &mut bone_cells[i * bone_ways..(i + 1) * bone_ways];
                        &mut BoneCell::of(ways, slot).warm
                    }
                };
                let last = (*cell != NO_TRIANGLE).then_some(*cell);
                let full = full && (surface.is_deforming() || !self.walk_on_bones);
                let local = last.filter(|_| !full).and_then(|t| {
                    if search.walk {
                        surface.walk(q, t)
                    } else {
                        surface.on_triangle(q, t)
                    }
                });
                let Some(mut hit) = local.or_else(|| surface.closest_within(q, last, bound)) else {
                    continue;
                };
                // Outside a bone at rest, which side of it a contact
                // layer's vertex is on now decides whether Sliding throws
                // it back out.
                if self.walk_on_bones && rest_outside {
                    hit = surface.settle_side(q, hit, &mut side_memo[i], slot as u32);
                }
                *cell = hit.triangle;
                let claim = if hit.signed_distance < 0.0 && !surface.is_deforming() {
                    Claim::InsideBone(-hit.distance)
                } else {
                    Claim::Gap(hit.distance - gap)
                };
                if best
                    .as_ref()
                    .is_none_or(|(b, ..)| claim.beats(b, self.reach))
                {
                    best = Some((claim, hit, slot, gap, rest_outside));
                }
            }
            match best {
                Some((_, hit, slot, gap, rest_outside)) => {
                    let surface = self.targets.target(self.target_ids[slot]);
                    contact[i] = SlidingContact {
                        point: hit.point.into(),
                        normal: hit.normal.into(),
                        barycentric: hit.barycentric.into(),
                        target_w: surface.point_inverse_mass(hit.triangle, hit.barycentric.into()),
                        gap,
                        triangle: hit.triangle,
                        target: TargetSlot::new(slot),
                        outside: rest_outside,
                    };
                    // Only the feature projection reads the plane; it runs
                    // after a first iteration that comes here.
                    if search.feature_contacts {
                        plane[i] = surface.face_normal(hit.triangle);
                    }
                }
                None => {
                    let c = &mut contact[i];
                    c.target = TargetSlot::NONE;
                    (c.gap, c.outside) = (f32::INFINITY, true);
                }
            }
        }
    }
}
