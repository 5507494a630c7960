//! What the solver derives from one muscle and keeps between steps, owned
//! by the driver next to the muscle: the muscle itself (`crate::muscle`)
//! stays plain data — particles, constraints, parameters, maps.
//!
//! ```text
//! target_ids        the driver's index of each of the muscle's targets
//! candidate_warm    closest data's last triangle per (vertex, candidate)
//! bone_cells        bone contacts' last triangle and clearance per
//! bone_margin       (vertex, bone it is near); their margin per vertex
//! bone_poses        the bones' poses at the last check (margins hold while they stand)
//! bone_boxes        the bones' world boxes, for bone contacts
//! side_memo         per vertex, its last winding-number sides of its bones
//! switched_on       the Soft, Hard and Sliding constraints that are on, this substep
//! plan, jacobi      colour plan / Jacobi incidence of the method in use
//! momentum          a free muscle's momentum, recorded at the substep's start
//! ```
//!
//! A derived structure remembers the muscle's [`Muscle::topology`] it was
//! built for; the muscle bumps that counter whenever its constraints are
//! relinked or switched on or off, so staleness is an integer compare.

use super::bone_boxes::BoneBoxes;
use super::coloring::ColorPlan;
use super::jacobi::JacobiState;
use super::momentum::RigidMomentum;
use crate::closest::{NO_TRIANGLE, SideMemo};
use crate::constraints::{ConstraintBatch, TargetId};
use crate::muscle::{ConstraintKind, Muscle};
use glam::{Vec3, Vec4};

/// Most bone cells per Sliding constraint ([`MuscleWorkspace::bone_cells`]):
/// a vertex is in the boxes of a handful of bones at once (a muscle with
/// fewer bones among its targets has one cell per bone, and never forgets).
pub(crate) const MAX_BONE_WAYS: usize = 8;

/// Bone contacts' memory of one bone near one vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct BoneCell {
    /// Where the vertex was, in the bone's frame, and how far it was from
    /// the bone then (`w`; 0 = unknown). A rigid bone's distance is
    /// 1-Lipschitz in the vertex position, so while the vertex stays within
    /// that distance of that point it cannot have entered the bone.
    pub clearance: Vec4,
    /// The bone's target slot; `u32::MAX` for an empty cell.
    pub slot: u32,
    /// The last closest triangle on the bone, or [`NO_TRIANGLE`]: where
    /// the next walk starts.
    pub warm: u32,
}

impl BoneCell {
    /// A cell that remembers nothing.
    pub const EMPTY: Self = Self {
        clearance: Vec4::ZERO,
        slot: u32::MAX,
        warm: NO_TRIANGLE,
    };

    /// The cell of `slot` among one vertex's `cells`: the one that holds
    /// it, or else one to take over — an empty one, or the one whose bone
    /// was farthest (its clearance is the least likely to be needed),
    /// emptied for `slot`.
    pub fn of(cells: &mut [BoneCell], slot: usize) -> &mut BoneCell {
        let slot = slot as u32;
        let k = match cells.iter().position(|c| c.slot == slot) {
            Some(k) => k,
            None => {
                let k = (0..cells.len())
                    .max_by(|&a, &b| {
                        let far = |c: &BoneCell| match c.slot {
                            u32::MAX => f32::INFINITY,
                            _ => c.clearance.w,
                        };
                        far(&cells[a]).total_cmp(&far(&cells[b])).then(b.cmp(&a))
                    })
                    .expect("a vertex has bone cells");
                cells[k] = BoneCell {
                    slot,
                    ..BoneCell::EMPTY
                };
                k
            }
        };
        &mut cells[k]
    }
}

/// A muscle's solver state (module docs).
#[derive(Clone, Debug, Default)]
pub struct MuscleWorkspace {
    /// The driver's index of each of the muscle's targets, in the muscle's
    /// target order (the solver's table index; `0..k` for a driver that
    /// passes the targets themselves).
    pub target_ids: Vec<TargetId>,
    /// Closest data's last closest triangle per entry of the Sliding
    /// batch's `candidates` (beside it), or [`NO_TRIANGLE`]: where the next
    /// walk of that target starts. A bone's is kept in `bone_cells`
    /// instead, shared with the bone contacts (a skin sharing them folded
    /// 93 triangles as the walk began, not sharing them 148).
    pub(crate) candidate_warm: Vec<u32>,
    /// Bone contacts' and closest data's memory of the bones each Sliding
    /// constraint's vertex is near: `bone_ways` cells per constraint (`bone_cells[i *
    /// bone_ways..]`), a small cache in place of a row per target (a skin
    /// vertex has every bone of a body as a target and is in the boxes of
    /// a few).
    pub(crate) bone_cells: Vec<BoneCell>,
    /// Bone cells per Sliding constraint: the muscle's bone targets, at
    /// most [`MAX_BONE_WAYS`].
    pub(crate) bone_ways: usize,
    /// Bone contacts' margin per Sliding constraint while its bones do not
    /// move (between a substep's iterations, or longer where they stand
    /// still): where the vertex was at its last full check, and how far it
    /// can move from there before one of its `clearance` cells needs a
    /// check (0 for a vertex left unchecked, a pinned one).
    pub(crate) bone_margin: Vec<Vec4>,
    /// The poses of the muscle's bones (its rigid targets, in slot order)
    /// at bone contacts' last check: a substep's first check trusts the
    /// margins when none moved since.
    pub(crate) bone_poses: Vec<glam::Affine3A>,
    /// Bone contacts' world boxes of the muscle's bones, packed: rebuilt
    /// in a substep's first iteration (bones are posed once per substep)
    /// and after a relink (emptied).
    pub(crate) bone_boxes: BoneBoxes,
    /// Bone contacts' position of each Sliding constraint's vertex after
    /// its check, written back to the muscle once every vertex is checked
    /// (the checks run in parallel chunks).
    pub(crate) bone_settled: Vec<Vec3>,
    /// Per Sliding constraint, its vertex's last winding-number decisions
    /// of its sides of the bones near it, shared by closest data and bone
    /// contacts (see [`SideMemo`]); sized at link.
    pub(crate) side_memo: Vec<SideMemo>,
    /// The Soft, Hard and Sliding constraints that are on, listed by
    /// closest data in each substep's first iteration.
    pub(crate) switched_on: SwitchedOn,
    /// The colour plan of a coloured method, with the topology it was built
    /// for.
    pub(crate) plan: Option<(u64, ColorPlan)>,
    /// The Jacobi incidence, with the topology it was built for.
    pub(crate) jacobi: Option<(u64, JacobiState)>,
    /// Where the muscle leads a group of muscles of its topology: whether
    /// the group runs in lanes, and its lanes (`super::lane_groups`).
    pub(crate) lane_group: super::lane_groups::LaneGroup,
    /// A free muscle's momentum, recorded at the start of the substep.
    pub(crate) momentum: Option<RigidMomentum>,
    /// The muscle's last good frame, for the run-time guard.
    pub(crate) last_good: super::guard::LastGood,
    /// The muscle's snapshot for the next iteration, staged by its own task
    /// ([`super::pipeline::stage_snapshot`]) when the driver asks.
    pub(crate) staged: StagedSnapshot,
}

/// The indices of the connections with a finite compliance (on),
/// ascending: the Soft and Hard whose goals closest data moves, and the
/// Soft, Hard and Sliding that Gauss–Seidel projects. A weight changes
/// between steps, never within one: closest data lists them in a substep's
/// first iteration ([`SwitchedOn::list`]).
#[derive(Clone, Debug, Default)]
pub(crate) struct SwitchedOn {
    /// Soft constraints that are on.
    pub soft: Vec<u32>,
    /// Hard constraints that are on.
    pub hard: Vec<u32>,
    /// Sliding constraints that are on.
    pub sliding: Vec<u32>,
    /// Sliding constraints whose vertex connects at all
    /// ([`crate::constraints::SlidingBatch::connected`]), on or off: the
    /// ones closest data visits. T7's muscles have a tenth of their
    /// vertices in a contact band; going over the others to skip them was
    /// two fifths of the Sliding part of closest data, in mispredicted
    /// branches.
    pub sliding_connected: Vec<u32>,
}

impl SwitchedOn {
    /// Lists the connections of `m` that are on (not
    /// [`ConstraintBatch::is_off`]), and the Sliding constraints whose
    /// vertex connects.
    pub fn list(&mut self, m: &Muscle) {
        /// The indices of `flags` that are set, into `list`.
        fn list(flags: impl Iterator<Item = bool>, list: &mut Vec<u32>) {
            list.clear();
            let set = flags.enumerate().filter(|&(_, set)| set);
            list.extend(set.map(|(i, _)| i as u32));
        }
        let c = &m.constraints;
        c.soft.list_on(&mut self.soft);
        c.hard.list_on(&mut self.hard);
        c.sliding.list_on(&mut self.sliding);
        list(
            c.sliding.connected.iter().copied(),
            &mut self.sliding_connected,
        );
    }

    /// The list for constraints of `kind`, if it keeps one.
    pub fn of(&self, kind: ConstraintKind) -> Option<&[u32]> {
        match kind {
            ConstraintKind::Soft => Some(&self.soft),
            ConstraintKind::Hard => Some(&self.hard),
            ConstraintKind::Sliding => Some(&self.sliding),
            _ => None,
        }
    }
}

/// A muscle's surface positions staged for its snapshot at the end of its
/// iteration's task, so that the driver publishes the next iteration's
/// snapshots by swapping buffers, with no pass over the muscles (a fork and
/// join on the threads) of its own.
#[derive(Clone, Debug, Default)]
pub(crate) struct StagedSnapshot {
    /// The driver's index of the muscle's own target, when others target
    /// it and the driver publishes by staging (`None`: it does not).
    pub target: Option<TargetId>,
    /// The surface positions.
    pub positions: Vec<Vec3>,
    /// Their [`crate::closest::TargetSurface::moved_squared`].
    pub moved_squared: f32,
    /// Staged since the last publish.
    pub ready: bool,
}

impl MuscleWorkspace {
    /// Resets the closest-data caches for `m`'s connections (after a link),
    /// keeping `target_ids`.
    pub(crate) fn reset_caches(&mut self, m: &Muscle) {
        let s = &m.constraints.sliding;
        self.candidate_warm.clear();
        self.candidate_warm.resize(s.candidates.len(), NO_TRIANGLE);
        self.bone_ways = s.rigid.iter().filter(|&&r| r).count().min(MAX_BONE_WAYS);
        self.bone_cells.clear();
        self.bone_cells
            .resize(s.len() * self.bone_ways, BoneCell::EMPTY);
        self.bone_margin.clear();
        self.bone_margin
            .resize(m.constraints.sliding.len(), Vec4::ZERO);
        self.bone_poses.clear();
        self.bone_boxes.clear();
        self.side_memo.clear();
        self.side_memo.resize(s.len(), SideMemo::default());
        self.switched_on = SwitchedOn::default();
    }

    /// The colour plan in use, if any (for reports and debug views).
    pub fn plan(&self) -> Option<&ColorPlan> {
        self.plan.as_ref().map(|(_, p)| p)
    }

    /// Whether the muscle's connections have been linked against targets
    /// (`target_ids` set by [`super::pipeline::link`]).
    pub fn is_linked(&self, m: &Muscle) -> bool {
        self.target_ids.len() == m.targets.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bone keeps its cell; a new bone takes an empty cell, then the cell
    /// of the farthest bone, emptied for it.
    #[test]
    fn a_bone_cell_is_kept_or_taken_from_the_farthest_bone() {
        let mut cells = [BoneCell::EMPTY; 3];
        for (slot, far) in [(7, 0.02), (3, 0.05), (9, 0.01)] {
            let c = BoneCell::of(&mut cells, slot);
            assert_eq!(
                (c.slot, c.warm, c.clearance),
                (slot as u32, NO_TRIANGLE, Vec4::ZERO)
            );
            (c.warm, c.clearance) = (11, Vec4::new(0.0, 0.0, 0.0, far));
        }
        assert_eq!(
            cells.map(|c| c.slot),
            [7, 3, 9],
            "empty cells first, in order"
        );
        assert_eq!(
            BoneCell::of(&mut cells, 3).warm,
            11,
            "a known bone keeps its cell"
        );
        let c = BoneCell::of(&mut cells, 4);
        assert_eq!((c.slot, c.warm, c.clearance.w), (4, NO_TRIANGLE, 0.0));
        assert_eq!(
            cells.map(|c| c.slot),
            [7, 4, 9],
            "the farthest bone (3) gave way"
        );
    }

    /// Gauss–Seidel over the connections that are on gives the bits of the
    /// pass over every connection: P3 (Soft, Hard and Sliding all used),
    /// a third of each switched off.
    #[test]
    fn gauss_seidel_over_the_connections_that_are_on_is_the_whole_pass() {
        use crate::constraints::VolumeProjection;
        use crate::solver::pipeline::{gauss_seidel, gauss_seidel_over};
        let mut solver = crate::scene::builtin("P3")
            .unwrap()
            .instantiate(std::path::Path::new("."))
            .unwrap();
        for _ in 0..5 {
            solver.step();
        }
        let mut m = solver.muscles()[0].clone();
        let c = &mut m.constraints;
        for compliance in [
            &mut c.soft.compliance,
            &mut c.hard.compliance,
            &mut c.sliding.compliance,
        ] {
            let on: Vec<usize> = (0..compliance.len())
                .filter(|&i| compliance[i].is_finite())
                .collect();
            assert!(on.len() > 3, "P3 has connections on");
            for &i in on.iter().step_by(3) {
                compliance[i] = f32::INFINITY;
            }
        }
        for (i, p) in m.p.iter_mut().enumerate() {
            *p += 1e-3 * Vec3::new((i as f32).sin(), (i as f32 * 0.7).cos(), 0.3);
        }
        let mut on = SwitchedOn::default();
        on.list(&m);
        let order = ConstraintKind::CANONICAL_ORDER;
        let (mut all, mut listed) = (m.clone(), m);
        gauss_seidel(&mut all, &order, 3600.0);
        gauss_seidel_over(
            &mut listed,
            &order,
            3600.0,
            Some(&on),
            VolumeProjection::Converge,
        );
        assert_eq!(all.p, listed.p);
        let (a, l) = (&all.constraints, &listed.constraints);
        assert_eq!(a.soft.lambda, l.soft.lambda);
        assert_eq!(a.hard.lambda, l.hard.lambda);
        assert_eq!(a.sliding.lambda, l.sliding.lambda);
        assert!(
            all.p
                .iter()
                .zip(&solver.muscles()[0].p)
                .any(|(a, b)| a != b)
        );
    }
}
