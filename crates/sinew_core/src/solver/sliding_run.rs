//! A run of Sliding constraints' closest data: the batch's slices for a
//! range of its constraints and the workspace's cells for them, cut in
//! pieces that closest data fills in parallel ([`super::closest_data`]).

use super::closest_data::for_each_piece;
use super::workspace::BoneCell;
use crate::closest::SideMemo;
use crate::constraints::{ParticleId, SlidingBatch, SlidingContact};
use glam::Vec3;

/// A run of Sliding constraints' closest data: the batch's slices for the
/// run, and the workspace's warm cells and side memos for it.
pub(super) struct SlidingRun<'a> {
    pub(super) particle: &'a [ParticleId],
    /// The run's constraints whose vertex connects, ascending, as indices
    /// into the batch (the run's own index plus `first`).
    pub(super) connected: &'a [u32],
    /// The batch index of the run's first constraint.
    pub(super) first: usize,
    pub(super) contact: &'a mut [SlidingContact],
    pub(super) plane: &'a mut [Vec3],
    /// The warm cells of the run's candidates (`candidate_warm` from the
    /// run's first candidate on).
    pub(super) warm: &'a mut [u32],
    /// The bone contacts' cells of the run's constraints, `bone_ways` each:
    /// a bone's warm triangle is theirs, shared (see
    /// [`super::workspace::MuscleWorkspace::bone_cells`]).
    pub(super) bone_cells: &'a mut [BoneCell],
    pub(super) bone_ways: usize,
    /// The batch's `rigid`: which target slots are bones.
    pub(super) rigid: &'a [bool],
    /// Per constraint, its last winding-number decision of a bone's side.
    pub(super) side_memo: &'a mut [SideMemo],
    /// The run's entries of the batch's `candidate_start` (one more than
    /// its constraints), into the whole `candidates`.
    pub(super) candidate_start: &'a [u32],
    pub(super) candidates: &'a [u32],
    /// The batch's `candidate_gap` and `candidate_outside`, beside
    /// `candidates`.
    pub(super) candidate_gap: &'a [f32],
    pub(super) candidate_outside: &'a [bool],
}

impl<'a> SlidingRun<'a> {
    /// The whole batch, with its `connected` constraints listed
    /// (`SwitchedOn::sliding_connected`) and the workspace's cells for it
    /// (`MuscleWorkspace::candidate_warm`, `bone_cells` of `bone_ways`
    /// each, `side_memo` sized to the batch).
    pub(super) fn of(
        s: &'a mut SlidingBatch,
        connected: &'a [u32],
        warm: &'a mut [u32],
        (bone_cells, bone_ways): (&'a mut [BoneCell], usize),
        side_memo: &'a mut [SideMemo],
    ) -> Self {
        Self {
            particle: &s.particle,
            connected,
            first: 0,
            contact: &mut s.contact,
            plane: &mut s.plane,
            warm,
            bone_cells,
            bone_ways,
            rigid: &s.rigid,
            side_memo,
            candidate_start: &s.candidate_start,
            candidates: &s.candidates,
            candidate_gap: &s.candidate_gap,
            candidate_outside: &s.candidate_outside,
        }
    }

    /// Runs `f` on runs of at most `k` constraints, in parallel on the
    /// current rayon pool.
    pub(super) fn for_each_chunk(self, k: usize, f: &(impl Fn(SlidingRun) + Sync)) {
        let n = self.particle.len();
        for_each_piece(self, n, k, &|run: Self, at| run.split_at(at), f);
    }

    /// The first `at` constraints and the rest.
    fn split_at(self, at: usize) -> (Self, Self) {
        let (particle, particle_b) = self.particle.split_at(at);
        let cut = (self.connected).partition_point(|&i| (i as usize) < self.first + at);
        let (connected, connected_b) = self.connected.split_at(cut);
        let (contact, contact_b) = self.contact.split_at_mut(at);
        let (plane, plane_b) = self.plane.split_at_mut(at);
        let first = self.candidate_start[at] - self.candidate_start[0];
        let (warm, warm_b) = self.warm.split_at_mut(first as usize);
        let bone_ways = self.bone_ways;
        let (bone_cells, bone_cells_b) = self.bone_cells.split_at_mut(at * bone_ways);
        let (side_memo, side_memo_b) = self.side_memo.split_at_mut(at);
        // Both halves keep the boundary entry.
        let (candidate_start, candidate_start_b) =
            (&self.candidate_start[..=at], &self.candidate_start[at..]);
        (
            Self {
                particle,
                connected,
                first: self.first,
                contact,
                plane,
                warm,
                bone_cells,
                bone_ways,
                rigid: self.rigid,
                side_memo,
                candidate_start,
                candidates: self.candidates,
                candidate_gap: self.candidate_gap,
                candidate_outside: self.candidate_outside,
            },
            Self {
                particle: particle_b,
                connected: connected_b,
                first: self.first + at,
                contact: contact_b,
                plane: plane_b,
                warm: warm_b,
                bone_cells: bone_cells_b,
                bone_ways,
                rigid: self.rigid,
                side_memo: side_memo_b,
                candidate_start: candidate_start_b,
                candidates: self.candidates,
                candidate_gap: self.candidate_gap,
                candidate_outside: self.candidate_outside,
            },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::closest_data::CLOSEST_CHUNK;
    use crate::solver::workspace::SwitchedOn;
    use std::sync::Mutex;

    /// Cut in chunks, a run hands each piece the connected constraints in
    /// its own range, as indices into the batch: together, once each, the
    /// batch's connected constraints and no other.
    #[test]
    fn chunks_share_out_the_connected_constraints_by_range() {
        let scene = super::super::tests::p1_with_skin(40, 30, {
            crate::muscle::MuscleParams::surface_layer(1.1, 0.01)
        });
        let mut solver = scene.instantiate(std::path::Path::new(".")).unwrap();
        solver.step();
        let (mut skin, mut ws) = (solver.muscles()[1].clone(), solver.workspaces()[1].clone());
        let n = skin.constraints.sliding.len();
        assert!(n > 4 * CLOSEST_CHUNK, "{n} Sliding constraints");
        // Every third vertex and a whole chunk's worth out of reach.
        let connected = &mut skin.constraints.sliding.connected;
        for (i, c) in connected.iter_mut().enumerate() {
            *c = i % 3 != 0 && !(300..600).contains(&i);
        }
        let expected: Vec<u32> = (0..n as u32).filter(|&i| connected[i as usize]).collect();
        let mut on = SwitchedOn::default();
        on.list(&skin);
        assert_eq!(on.sliding_connected, expected);
        let ways = ws.bone_ways;
        let run = SlidingRun::of(
            &mut skin.constraints.sliding,
            &on.sliding_connected,
            &mut ws.candidate_warm,
            (&mut ws.bone_cells, ways),
            &mut ws.side_memo,
        );
        let pieces = Mutex::new(Vec::new());
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap();
        pool.install(|| {
            run.for_each_chunk(CLOSEST_CHUNK, &|piece: SlidingRun| {
                let range = piece.first..piece.first + piece.particle.len();
                pieces
                    .lock()
                    .unwrap()
                    .push((range, piece.connected.to_vec()));
            })
        });
        let mut pieces = pieces.into_inner().unwrap();
        pieces.sort_by_key(|(range, _)| range.start);
        assert!(pieces.len() > 4, "{} pieces", pieces.len());
        let mut next = 0;
        for (range, listed) in &pieces {
            assert_eq!(range.start, next);
            assert!(range.len() <= CLOSEST_CHUNK);
            assert!(listed.iter().all(|&i| range.contains(&(i as usize))));
            next = range.end;
        }
        assert_eq!(next, n);
        let all: Vec<u32> = pieces.into_iter().flat_map(|(_, l)| l).collect();
        assert_eq!(all, expected);
    }
}
