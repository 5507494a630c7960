//! Closest data (BE5, SPEC §6): for every Sliding constraint the closest
//! point on the target it slides on, and the current goals of Soft and Hard
//! on their rest triangles. It reads the targets through [`TargetSet`] (the
//! driver's table indexed by [`MuscleWorkspace::target_ids`]) and keeps its
//! caches in the workspace. The bone contacts that end an iteration are in
//! [`super::bone_contacts`].

use super::params::ClosestSchedule;
use super::sliding_run::SlidingRun;
use super::workspace::{BoneCell, MuscleWorkspace};
use crate::closest::{ClosestHit, NO_TRIANGLE, TargetSet, TargetSurface};
use crate::constraints::{PointBatch, SlidingContact, TargetId, TargetSlot};
use crate::muscle::{Muscle, SurfaceAnchor};
use crate::prefetch::prefetch;
use glam::Vec3;

/// Sliding constraints per parallel chunk of the closest-data block (a few
/// hundred ns each, so a chunk is worth a fork and join).
pub const CLOSEST_CHUNK: usize = 256;

/// Closest data (BE5): Sliding's closest point on the closest target per
/// vertex, and the current goals of the Soft and Hard that are on, on their
/// rest triangles.
/// With `search.split` the vertices are split over the current rayon pool
/// in chunks of `CLOSEST_CHUNK` (each vertex writes only its own data, so
/// the result is the same).
pub fn closest_data<T: TargetSet + Sync + ?Sized>(
    m: &mut Muscle,
    ws: &mut MuscleWorkspace,
    targets: &T,
    search: ClosestSchedule,
) {
    // Which connections are on, for the substep's iterations.
    if search.first_of_substep {
        ws.switched_on.list(m);
    }
    let nt = ws.target_ids.len();
    if nt == 0 {
        return;
    }
    let reach = m.contact_reach();
    let c = &mut m.constraints;
    // A contact layer walks in a substep's first iteration only.
    let walk = search.walk && (!c.sliding.walk_first_only || search.first_of_substep);
    let input = SlidingInput {
        p: &m.p,
        target_ids: &ws.target_ids,
        targets,
        search: ClosestSchedule { walk, ..search },
        reach,
        walk_on_bones: c.sliding.walk_first_only,
    };
    let run = SlidingRun::of(
        &mut c.sliding,
        &ws.switched_on.sliding_connected,
        &mut ws.candidate_warm,
        (&mut ws.bone_cells, ws.bone_ways),
        &mut ws.side_memo,
    );
    if search.split && run.particle.len() > CLOSEST_CHUNK {
        run.for_each_chunk(CLOSEST_CHUNK, &|run| input.closest(run));
    } else {
        input.closest(run);
    }
    tie_goals(m, ws, targets, search);
}

/// The current goals of the Soft and Hard constraints that are on (a finite
/// compliance), on their rest triangles. Which are on is listed in a
/// substep's first iteration ([`MuscleWorkspace::switched_on`]), so the
/// iterations visit only those: the anatomy scenes (T3–T7, the fitted
/// character) have them all off (weight 0), and going over T7's 2 × 20 448
/// switched-off ties in each of its ten iterations took about a twelfth of
/// its closest data.
fn tie_goals<T: TargetSet + ?Sized>(
    m: &mut Muscle,
    ws: &mut MuscleWorkspace,
    targets: &T,
    search: ClosestSchedule,
) {
    let c = &mut m.constraints;
    let on = &ws.switched_on;
    // Soft and Hard goals on a rigid target only move with its bone, which
    // is posed once per substep; a muscle target moves every iteration.
    let moved = |a: &SurfaceAnchor| {
        let t = targets.target(ws.target_ids[a.target.index()]);
        (search.first_of_substep || t.is_deforming()).then_some(t)
    };
    move_goals(&on.soft, &c.soft_anchor, &mut c.soft, moved, |t, a| {
        t.point_at(a.triangle, a.barycentric)
    });
    move_goals(&on.hard, &c.hard_anchor, &mut c.hard, moved, |t, a| {
        t.point_in_frame(a.triangle, a.barycentric, a.local)
    });
}

/// Moves the goal (`goal_at` on its target) and the target's inverse mass
/// of each tie listed in `on` whose target has `moved` (`Some`: the
/// target); a tie built without an anchor has no goal to move.
fn move_goals<'t>(
    on: &[u32],
    anchors: &[SurfaceAnchor],
    ties: &mut PointBatch,
    moved: impl Fn(&SurfaceAnchor) -> Option<&'t TargetSurface>,
    goal_at: impl Fn(&TargetSurface, &SurfaceAnchor) -> Vec3,
) {
    for &i in on {
        let i = i as usize;
        if let Some(a) = anchors.get(i)
            && let Some(t) = moved(a)
        {
            ties.goal[i] = goal_at(t, a);
            ties.target_w[i] = t.point_inverse_mass(a.triangle, a.barycentric);
        }
    }
}

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

/// Runs `f` on pieces of `run` (of `len` items) of at most `k` items each,
/// in parallel on the current rayon pool: `split(run, at)` cuts a piece
/// into its first `at` items and the rest, halving at a multiple of `k`,
/// so nothing is allocated. Each item's work must touch only its own
/// cells: the pieces then give the same bits for any thread count.
pub(super) fn for_each_piece<R: Send>(
    run: R,
    len: usize,
    k: usize,
    split: &(impl Fn(R, usize) -> (R, R) + Sync),
    f: &(impl Fn(R) + Sync),
) {
    if len <= k {
        return f(run);
    }
    let at = len.div_ceil(k) / 2 * k;
    let (head, tail) = split(run, at);
    rayon::join(
        || for_each_piece(head, at, k, split, f),
        || for_each_piece(tail, len - at, k, split, f),
    );
}

/// What the Sliding part of closest data reads.
struct SlidingInput<'a, T: ?Sized> {
    p: &'a [Vec3],
    target_ids: &'a [TargetId],
    targets: &'a T,
    search: ClosestSchedule,
    /// The muscle's contact reach: a target farther than this at rest is
    /// never chosen.
    reach: f32,
    /// A contact layer's nearest point on a bone is only ever walked to,
    /// never searched for anew once known (see [`crate::constraints::SlidingBatch::walk_first_only`]).
    walk_on_bones: bool,
}

impl<T: TargetSet + ?Sized> SlidingInput<'_, T> {
    /// Closest points for a run of Sliding constraints.
    fn closest(&self, run: SlidingRun) {
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
                if let Some(cell) = warm.get(from - candidate_start[0] as usize) {
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
            let base = candidate_start[0] as usize;
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
                        point: hit.point,
                        normal: hit.normal,
                        barycentric: hit.barycentric,
                        target_w: surface.point_inverse_mass(hit.triangle, hit.barycentric),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin;
    use crate::solver::params::ClosestSchedule;

    /// The Soft goals closest data moves are those of the ties that are on
    /// when the substep starts: in its first iteration every one of them
    /// (on any target), in a later one those on a muscle (a bone has not
    /// moved); a tie switched off between substeps keeps its goal.
    #[test]
    fn soft_goals_move_for_the_ties_that_are_on() {
        let mut solver = builtin("P3")
            .unwrap()
            .instantiate(std::path::Path::new("."))
            .unwrap();
        for _ in 0..5 {
            solver.step();
        }
        let targets = solver.targets.as_slice();
        let later = ClosestSchedule {
            first_of_frame: false,
            first_of_substep: false,
            ..ClosestSchedule::ALWAYS
        };
        let (mut m, mut ws) = (solver.muscles()[0].clone(), solver.workspaces()[0].clone());
        let anchors = m.constraints.soft_anchor.clone();
        let ids = ws.target_ids.clone();
        let target_of = |i: usize| targets.target(ids[anchors[i].target.index()]);
        let expected =
            |i: usize| target_of(i).point_at(anchors[i].triangle, anchors[i].barycentric);
        let on = |m: &Muscle, i: usize| m.constraints.soft.compliance[i].is_finite();
        // A third of the ties on switched off before the substep.
        let was_on: Vec<usize> = (0..anchors.len()).filter(|&i| on(&m, i)).collect();
        for &i in was_on.iter().step_by(3) {
            m.constraints.soft.compliance[i] = f32::INFINITY;
        }
        let unset = Vec3::splat(f32::NAN);
        let (mut moved_on_muscle, mut moved_on_bone) = (0, 0);
        for schedule in [ClosestSchedule::ALWAYS, later] {
            m.constraints.soft.goal.fill(unset);
            closest_data(&mut m, &mut ws, targets, schedule);
            for i in 0..anchors.len() {
                let goal = m.constraints.soft.goal[i];
                let moves = on(&m, i) && (schedule.first_of_substep || target_of(i).is_deforming());
                if moves {
                    assert_eq!(goal, expected(i), "tie {i}");
                    match target_of(i).is_deforming() {
                        true => moved_on_muscle += 1,
                        false => moved_on_bone += 1,
                    }
                } else {
                    assert!(goal.is_nan(), "tie {i} moved");
                }
            }
        }
        assert!(
            moved_on_muscle > 0 && moved_on_bone > 0,
            "{moved_on_muscle} / {moved_on_bone}"
        );
        assert!(was_on.len() > 3, "P3 has ties on");
    }
}
