//! Closest data (BE5, SPEC §6): for every Sliding constraint the closest
//! point on the target it slides on, and the current goals of Soft and Hard
//! on their rest triangles. It reads the targets through [`TargetSet`] (the
//! driver's table indexed by [`MuscleWorkspace::target_ids`]) and keeps its
//! caches in the workspace. The bone contacts that end an iteration are in
//! [`super::bone_contacts`].

use super::params::ClosestSchedule;
use super::sliding_closest::SlidingInput;
use super::sliding_run::SlidingRun;
use super::workspace::MuscleWorkspace;
use crate::closest::{TargetSet, TargetSurface};
use crate::constraints::PointBatch;
use crate::muscle::{Muscle, SurfaceAnchor};
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
    // A contact layer walks in a substep's first iteration only, and
    // re-projects onto the triangle in the others.
    let layer = c.sliding.walk_first_only;
    let walk = search.walk && (!layer || search.first_of_substep);
    let feature_contacts = search.feature_contacts && !layer;
    let input = SlidingInput {
        p: &m.p,
        target_ids: &ws.target_ids,
        targets,
        search: ClosestSchedule {
            walk,
            feature_contacts,
            ..search
        },
        reach,
        walk_on_bones: layer,
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
