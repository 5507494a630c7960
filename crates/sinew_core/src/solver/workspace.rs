//! What the solver derives from one muscle and keeps between steps, owned
//! by the driver next to the muscle: the muscle itself (`crate::muscle`)
//! stays plain data — particles, constraints, parameters, maps.
//!
//! ```text
//! target_ids        the driver's index of each of the muscle's targets
//! warm, clearance   closest data's last triangle and bone clearance per
//! bone_margin       (vertex, target); the bone contacts' margin per vertex
//! bone_boxes        the bones' world boxes, for bone contacts
//! side_memo         per vertex, its last winding-number side of a bone
//! plan, jacobi      colour plan / Jacobi incidence of the method in use
//! momentum          a free muscle's momentum, recorded at the substep's start
//! ```
//!
//! A derived structure remembers the muscle's [`Muscle::topology`] it was
//! built for; the muscle bumps that counter whenever its constraints are
//! relinked or switched on or off, so staleness is an integer compare.

use super::coloring::ColorPlan;
use super::jacobi::JacobiState;
use super::momentum::RigidMomentum;
use crate::closest::{NO_TRIANGLE, SideMemo};
use crate::constraints::TargetId;
use crate::muscle::Muscle;
use glam::{Vec3, Vec3A, Vec4};

/// A muscle's solver state (module docs).
#[derive(Clone, Debug, Default)]
pub struct MuscleWorkspace {
    /// The driver's index of each of the muscle's targets, in the muscle's
    /// target order (the solver's table index; `0..k` for a driver that
    /// passes the targets themselves).
    pub target_ids: Vec<TargetId>,
    /// The last closest triangle per (Sliding constraint, target slot),
    /// `warm[i * targets + t]`, or [`NO_TRIANGLE`]: where the next walk of
    /// that target starts (4 bytes a cell keeps the full body's table in
    /// cache).
    pub(crate) warm: Vec<u32>,
    /// Bone contacts' clearance per (Sliding constraint, target slot), as
    /// `warm`: where the vertex was, in the bone's frame, and how far it was
    /// from the bone then (0 = unknown). A rigid bone's distance is
    /// 1-Lipschitz in the vertex position, so while the vertex stays within
    /// that distance of that point it cannot have entered the bone.
    pub(crate) clearance: Vec<Vec4>,
    /// Bone contacts' margin per Sliding constraint within a substep (bones
    /// do not move between its iterations): where the vertex was at the
    /// substep's first check, and how far it can move from there before one
    /// of its `clearance` cells needs a check.
    pub(crate) bone_margin: Vec<Vec4>,
    /// Bone contacts' packed world boxes of the muscle's bones, `(target
    /// slot, min, max)`: rebuilt in a substep's first iteration (bones are
    /// posed once per substep) and after a relink (emptied).
    pub(crate) bone_boxes: Vec<(usize, Vec3A, Vec3A)>,
    /// `bone_boxes` in consecutive groups, `(end, min, max)`: each group's
    /// entries end at `end` (exclusive) and its box holds their boxes.
    pub(crate) bone_groups: Vec<(usize, Vec3A, Vec3A)>,
    /// Bone contacts' position of each Sliding constraint's vertex after
    /// its check, written back to the muscle once every vertex is checked
    /// (the checks run in parallel chunks).
    pub(crate) bone_settled: Vec<Vec3>,
    /// Closest data's last winding-number decision of a bone's side per
    /// Sliding constraint (see [`SideMemo`]).
    pub(crate) side_memo: Vec<SideMemo>,
    /// The colour plan of a coloured method, with the topology it was built
    /// for.
    pub(crate) plan: Option<(u64, ColorPlan)>,
    /// The Jacobi incidence, with the topology it was built for.
    pub(crate) jacobi: Option<(u64, JacobiState)>,
    /// A free muscle's momentum, recorded at the start of the substep.
    pub(crate) momentum: Option<RigidMomentum>,
    /// The muscle's last good frame, for the run-time guard.
    pub(crate) last_good: super::guard::LastGood,
}

impl MuscleWorkspace {
    /// Resets the closest-data caches for `m`'s connections (after a link),
    /// keeping `target_ids`.
    pub(crate) fn reset_caches(&mut self, m: &Muscle) {
        let cells = m.constraints.sliding.len() * self.target_ids.len();
        self.warm.clear();
        self.warm.resize(cells, NO_TRIANGLE);
        self.clearance.clear();
        self.clearance.resize(cells, Vec4::ZERO);
        self.bone_margin.clear();
        self.bone_margin
            .resize(m.constraints.sliding.len(), Vec4::ZERO);
        self.bone_boxes.clear();
        self.bone_groups.clear();
        self.side_memo.clear();
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
