//! Graph colouring of a muscle's constraints (SPEC §9.3, the thesis' SMT-G).
//!
//! Constraints that share no particle can be projected at the same time. A
//! colouring splits a muscle's constraints into groups with that property:
//! groups run one after the other, the constraints inside a group in any
//! order (or in parallel) with the same result as Gauss–Seidel.
//!
//! [`ColorGroups::greedy`] is the thesis' build: each constraint, in creation
//! order, joins the first group that shares no particle with it, or opens a
//! new one. Targets are read-only, so Sliding, Soft and Hard touch one
//! particle each; the Volume constraint touches every surface particle and
//! stays outside the groups (a reduction of its own). The internal points are
//! what makes this colouring long: every Internal constraint of one internal
//! point needs a group of its own, so the group count is at least the largest
//! number of surface vertices tied to one internal point (SPEC §9.3,
//! Appendix A: 65 groups for the biceps, 16 of them with one constraint).

use crate::constraints::{ConstraintBatch, ConstraintKind, Correction};
use crate::muscle::Muscle;

/// One constraint of a muscle: its type and index in that type's batch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ConstraintRef {
    /// Constraint type.
    pub kind: ConstraintKind,
    /// Index in the batch of `kind`.
    pub index: u32,
}

/// Constraint groups of one muscle in which no two constraints share a
/// particle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ColorGroups {
    /// The groups, in solve order.
    pub groups: Vec<Vec<ConstraintRef>>,
}

/// The particles constraint `c` of `m` moves (targets are read-only).
pub fn particles_of(m: &Muscle, c: ConstraintRef) -> [Option<u32>; 2] {
    let k = &m.constraints;
    let i = c.index as usize;
    match c.kind {
        ConstraintKind::Attach => [Some(k.attach.particle[i]), None],
        ConstraintKind::BranchAttach => [Some(k.branch_attach.particle[i]), None],
        ConstraintKind::Hard => [Some(k.hard.particle[i]), None],
        ConstraintKind::Soft => [Some(k.soft.particle[i]), None],
        ConstraintKind::Sliding => [Some(k.sliding.particle[i]), None],
        ConstraintKind::Branch => [Some(k.branch.a[i]), Some(k.branch.b[i])],
        ConstraintKind::Internal => [Some(k.internal.a[i]), Some(k.internal.b[i])],
        ConstraintKind::Fiber => [Some(k.fiber.a[i]), Some(k.fiber.b[i])],
        ConstraintKind::Volume => [None, None],
    }
}

/// Every constraint of `m` except Volume, type by type in `order`.
pub fn constraints_in_order(m: &Muscle, order: &[ConstraintKind]) -> Vec<ConstraintRef> {
    let k = &m.constraints;
    let mut out = Vec::new();
    for &kind in order {
        let len = match kind {
            ConstraintKind::Attach => k.attach.particle.len(),
            ConstraintKind::BranchAttach => k.branch_attach.particle.len(),
            ConstraintKind::Hard => k.hard.particle.len(),
            ConstraintKind::Soft => k.soft.particle.len(),
            ConstraintKind::Sliding => k.sliding.particle.len(),
            ConstraintKind::Branch => k.branch.len(),
            ConstraintKind::Internal => k.internal.len(),
            ConstraintKind::Fiber => k.fiber.len(),
            ConstraintKind::Volume => 0,
        };
        out.extend((0..len as u32).map(|index| ConstraintRef { kind, index }));
    }
    out
}

impl ColorGroups {
    /// Greedy first-fit colouring in creation order (`order`, type by type).
    pub fn greedy(m: &Muscle, order: &[ConstraintKind]) -> Self {
        let particles = m.x.len();
        // used[g][p]: particle p is already moved by a constraint of group g.
        let mut used: Vec<Vec<bool>> = Vec::new();
        let mut groups: Vec<Vec<ConstraintRef>> = Vec::new();
        for c in constraints_in_order(m, order) {
            let touched = particles_of(m, c);
            let free = |mask: &Vec<bool>| touched.iter().flatten().all(|&p| !mask[p as usize]);
            let g = match used.iter().position(free) {
                Some(g) => g,
                None => {
                    used.push(vec![false; particles]);
                    groups.push(Vec::new());
                    groups.len() - 1
                }
            };
            for &p in touched.iter().flatten() {
                used[g][p as usize] = true;
            }
            groups[g].push(c);
        }
        Self { groups }
    }

    /// Number of groups (sweeps per iteration).
    pub fn len(&self) -> usize {
        self.groups.len()
    }

    /// True when there are no groups.
    pub fn is_empty(&self) -> bool {
        self.groups.is_empty()
    }

    /// Group sizes, in solve order.
    pub fn sizes(&self) -> Vec<usize> {
        self.groups.iter().map(Vec::len).collect()
    }
}

/// A muscle's colour groups and the scratch a parallel sweep writes into.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ColoredState {
    /// The groups.
    pub groups: ColorGroups,
    /// One slot per constraint of the largest group.
    corrections: Vec<Option<Correction>>,
}

impl ColoredState {
    /// Greedy groups of `m` in `order` (see [`ColorGroups::greedy`]).
    pub fn new(m: &Muscle, order: &[ConstraintKind]) -> Self {
        let groups = ColorGroups::greedy(m, order);
        let largest = groups.groups.iter().map(Vec::len).max().unwrap_or(0);
        Self {
            groups,
            corrections: vec![None; largest],
        }
    }
}

/// Groups smaller than this are computed on the calling thread: below it the
/// fork and join cost more than the work.
pub const PARALLEL_GROUP: usize = 256;

/// Projection of constraint `c` of `m` at the current predictions, not yet
/// written (Volume has none: it is solved apart).
pub fn correction(m: &Muscle, c: ConstraintRef, inv_h2: f32) -> Option<Correction> {
    let (k, p, w, i) = (&m.constraints, &m.p, &m.w, c.index as usize);
    match c.kind {
        ConstraintKind::Attach => k.attach.correction(i, p, w, inv_h2),
        ConstraintKind::BranchAttach => k.branch_attach.correction(i, p, w, inv_h2),
        ConstraintKind::Hard => k.hard.correction(i, p, w, inv_h2),
        ConstraintKind::Soft => k.soft.correction(i, p, w, inv_h2),
        ConstraintKind::Sliding => k.sliding.correction(i, p, w, inv_h2),
        ConstraintKind::Branch => k.branch.correction(i, p, w, inv_h2),
        ConstraintKind::Internal => k.internal.correction(i, p, w, inv_h2),
        ConstraintKind::Fiber => k.fiber.correction(i, p, w, inv_h2),
        ConstraintKind::Volume => None,
    }
}

/// Writes a correction of constraint `c` of `m`.
pub fn commit(m: &mut Muscle, c: ConstraintRef, correction: &Correction) {
    let (k, p, i) = (&mut m.constraints, &mut m.p, c.index as usize);
    match c.kind {
        ConstraintKind::Attach => k.attach.commit(i, correction, p),
        ConstraintKind::BranchAttach => k.branch_attach.commit(i, correction, p),
        ConstraintKind::Hard => k.hard.commit(i, correction, p),
        ConstraintKind::Soft => k.soft.commit(i, correction, p),
        ConstraintKind::Sliding => k.sliding.commit(i, correction, p),
        ConstraintKind::Branch => k.branch.commit(i, correction, p),
        ConstraintKind::Internal => k.internal.commit(i, correction, p),
        ConstraintKind::Fiber => k.fiber.commit(i, correction, p),
        ConstraintKind::Volume => {}
    }
}

/// One coloured sweep over every constraint of `m` but Volume: the groups
/// one after the other; inside a group every correction is computed from the
/// same positions, in parallel when `parallel` and the group is large, then
/// written. Constraints of a group share no particle, so this is
/// Gauss–Seidel in group order, and the same for any thread count.
pub fn project_colored(m: &mut Muscle, state: &mut ColoredState, inv_h2: f32, parallel: bool) {
    use rayon::prelude::*;
    for group in &state.groups.groups {
        if parallel && group.len() >= PARALLEL_GROUP {
            let slots = &mut state.corrections[..group.len()];
            let muscle: &Muscle = m;
            slots
                .par_iter_mut()
                .zip(group.par_iter())
                .for_each(|(slot, &c)| *slot = correction(muscle, c, inv_h2));
            for (slot, &c) in slots.iter().zip(group) {
                if let Some(corr) = slot {
                    commit(m, c, corr);
                }
            }
        } else {
            for &c in group {
                if let Some(corr) = correction(m, c, inv_h2) {
                    commit(m, c, &corr);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin;
    use std::collections::HashSet;

    fn muscles(scene: &str) -> Vec<Muscle> {
        let mut solver = builtin(scene)
            .unwrap()
            .instantiate(std::path::Path::new("."))
            .unwrap();
        // One step links the target connections (Sliding, Soft, Hard).
        solver.step();
        solver.muscles().to_vec()
    }

    #[test]
    fn no_group_shares_a_particle_and_every_constraint_is_in_exactly_one() {
        for scene in ["P1", "P2", "P3"] {
            for m in muscles(scene) {
                let order = ConstraintKind::CANONICAL_ORDER;
                let colors = ColorGroups::greedy(&m, &order);
                for (g, group) in colors.groups.iter().enumerate() {
                    let mut seen = HashSet::new();
                    for &c in group {
                        for p in particles_of(&m, c).into_iter().flatten() {
                            assert!(
                                seen.insert(p),
                                "{scene}: group {g} moves particle {p} twice"
                            );
                        }
                    }
                }
                let all: Vec<ConstraintRef> = colors.groups.concat();
                let unique: HashSet<ConstraintRef> = all.iter().copied().collect();
                assert_eq!(
                    all.len(),
                    unique.len(),
                    "{scene}: a constraint in two groups"
                );
                let expected = m.counts().total() - usize::from(m.constraints.volume.is_some());
                assert_eq!(all.len(), expected, "{scene}: constraints missing");
            }
        }
    }

    #[test]
    fn group_count_is_bounded_below_by_the_busiest_particle() {
        // A particle moved by d constraints needs d different groups; greedy
        // first-fit never needs more than (max constraints sharing a particle
        // with one constraint) + 1.
        for m in muscles("P3") {
            let refs = constraints_in_order(&m, &ConstraintKind::CANONICAL_ORDER);
            let mut degree = vec![0usize; m.x.len()];
            for &c in &refs {
                for p in particles_of(&m, c).into_iter().flatten() {
                    degree[p as usize] += 1;
                }
            }
            let max_degree = *degree.iter().max().unwrap();
            let colors = ColorGroups::greedy(&m, &ConstraintKind::CANONICAL_ORDER);
            assert!(colors.len() >= max_degree);
            let max_conflicts = refs
                .iter()
                .map(|&c| {
                    particles_of(&m, c)
                        .into_iter()
                        .flatten()
                        .map(|p| degree[p as usize] - 1)
                        .sum::<usize>()
                })
                .max()
                .unwrap();
            assert!(colors.len() <= max_conflicts + 1);
        }
    }
}
