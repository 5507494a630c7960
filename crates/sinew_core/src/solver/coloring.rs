//! Graph colouring of a muscle's constraints (SPEC §9.3, the thesis' SMT-G,
//! and beyond it).
//!
//! Constraints that share no particle can be projected at the same time. A
//! colouring splits a muscle's constraints into colours with that property:
//! colours run one after the other, the work inside a colour in any order
//! (or in parallel) with the same result as Gauss–Seidel.
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
//!
//! A [`ColorPlan`] is what the solver runs: colours of *units* (runs of
//! constraints one thread solves in order), packed with their parallel
//! chunks. [`ColorPlan::per_constraint`] is the thesis' colouring,
//! [`ColorPlan::clustered`] the global scope's (vertex and star units: the
//! arm needs 15 colours instead of 24), [`ColorPlan::hybrid`] Hybrid's big
//! colours plus a Jacobi tail. `sweep.rs` runs them.

use super::jacobi::JacobiState;
use super::sweep::{PlannedConstraint, Segment, SweepPlan};
use crate::constraints::ParticleId;
use crate::muscle::Muscle;
use crate::muscle::{ConstraintCounts, ConstraintKind};

pub use super::constraint_ref::{
    ConstraintRef, commit, constraints_in_order, correction, particles_of,
};
use super::constraint_ref::{batch_particles, index_arrays, is_off, off_flags, off_flags_match};

/// Constraint groups of one muscle in which no two constraints share a
/// particle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ColorGroups {
    /// The groups, in solve order.
    pub groups: Vec<Vec<ConstraintRef>>,
}

impl ColorGroups {
    /// Greedy first-fit colouring in creation order (`order`, type by type).
    pub fn greedy(m: &Muscle, order: &[ConstraintKind]) -> Self {
        let units: Vec<Vec<ConstraintRef>> = constraints_in_order(m, order)
            .into_iter()
            .map(|c| vec![c])
            .collect();
        let groups = greedy_units(m, &units)
            .into_iter()
            .map(|color| color.into_iter().map(|u| units[u][0]).collect())
            .collect();
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

/// Greedy first-fit over units (runs of constraints one thread solves in
/// order): each unit, in the given order, joins the first colour none of
/// whose units shares a particle with it. Returns unit indices per colour.
fn greedy_units(m: &Muscle, units: &[Vec<ConstraintRef>]) -> Vec<Vec<usize>> {
    let particles = m.x.len();
    // used[c][p]: particle p is already moved by a unit of colour c.
    let mut used: Vec<Vec<bool>> = Vec::new();
    let mut colors: Vec<Vec<usize>> = Vec::new();
    let mut touched = Vec::new();
    for (u, unit) in units.iter().enumerate() {
        touched.clear();
        touched.extend(unit.iter().flat_map(|&c| particles_of(m, c)).flatten());
        let free = |mask: &Vec<bool>| touched.iter().all(|&p| !mask[p.index()]);
        let c = match used.iter().position(free) {
            Some(c) => c,
            None => {
                used.push(vec![false; particles]);
                colors.push(Vec::new());
                colors.len() - 1
            }
        };
        for &p in &touched {
            used[c][p.index()] = true;
        }
        colors[c].push(u);
    }
    colors
}

/// How a [`ColorPlan`] was built; a plan is rebuilt when the method asks for
/// another.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlanKind {
    /// One constraint per unit, greedy in creation order (the thesis' SMT-G).
    PerConstraint,
    /// Clustered units (see [`ColorPlan::clustered`]).
    Clustered,
    /// Per-constraint colours of at least `min_group` constraints; the rest
    /// is a Jacobi tail.
    Hybrid {
        /// Smallest colour solved Gauss–Seidel.
        min_group: u32,
    },
}

/// Constraints per chunk of a colour, the smallest piece of a colour a
/// thread takes: about 10 µs of work. Small enough that a skin's colours of
/// a few thousand constraints reach a dozen threads (with 1 024 a colour of
/// 3 000 went to three: the fitted character's skin took 6.8 ms a frame on
/// 16 threads, 4.4 ms with 256); a sweep groups chunks into tasks of
/// [`TASK_CONSTRAINTS`] while a colour has more than enough chunks for
/// every thread. Chunking never changes the result: the chunks of a colour
/// share no particle.
pub const CHUNK_CONSTRAINTS: usize = 256;

/// Constraints a parallel task takes at least while there is work enough
/// for every thread (a colour's chunks, grouped; a Jacobi pass's
/// constraints): about 50 µs of work against about 10 µs for a fork and
/// join on the development machine (`sinew suite` measures both).
pub const TASK_CONSTRAINTS: usize = 1024;

/// A muscle's colouring, ready to run: colours one after the other; inside a
/// colour, *units* that share no particle, each a run of constraints solved
/// Gauss–Seidel in order by one thread; units are grouped into chunks of
/// about [`CHUNK_CONSTRAINTS`] constraints that threads take whole.
///
/// The constructor checks what the parallel sweep relies on: the units of a
/// colour share no particle and every constraint (but Volume) is in exactly
/// one unit or in the Jacobi tail. A plan is valid for the constraint counts
/// and particle count it was built for ([`ColorPlan::fits`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ColorPlan {
    /// Constraints in solve order: colour by colour, unit by unit.
    refs: Vec<ConstraintRef>,
    /// What the sweeps run: each chunk's constraints as runs of one type,
    /// with the particles they move copied from the muscle, checked for
    /// disjointness by the sweep module itself.
    sweep: SweepPlan,
    /// The particle indices of every constraint when the plan was built,
    /// batch by batch ([`index_arrays`]): what makes a colour's units
    /// disjoint, compared whole (a memory compare) by [`ColorPlan::fits`].
    tied: Vec<ParticleId>,
    /// Which constraints were switched off when the plan was built
    /// ([`off_flags`], batch by batch): the sweeps skip them, and
    /// [`ColorPlan::fits`] compares.
    off: Vec<bool>,
    /// `refs[units[u]..units[u + 1]]` is unit `u`.
    units: Vec<u32>,
    /// `units` of colour `c`: `colors[c]..colors[c + 1]`.
    colors: Vec<u32>,
    /// Chunk boundaries as unit indices.
    chunks: Vec<u32>,
    /// Hybrid: the constraints solved Jacobi after the colours.
    tail: Option<JacobiState>,
    kind: PlanKind,
    particles: usize,
    counts: ConstraintCounts,
}

impl ColorPlan {
    /// The plan `kind` asks for, over `m`'s constraints in `order`.
    pub fn build(m: &Muscle, order: &[ConstraintKind], kind: PlanKind) -> Self {
        match kind {
            PlanKind::PerConstraint => Self::per_constraint(m, order),
            PlanKind::Clustered => Self::clustered(m, order),
            PlanKind::Hybrid { min_group } => Self::hybrid(m, order, min_group as usize),
        }
    }

    /// The thesis' colouring: one constraint per unit (see [`ColorGroups::greedy`]).
    pub fn per_constraint(m: &Muscle, order: &[ConstraintKind]) -> Self {
        let groups = ColorGroups::greedy(m, order).groups;
        let colors = groups
            .into_iter()
            .map(|g| g.into_iter().map(|c| vec![c]).collect())
            .collect();
        Self::new(m, order, colors, Vec::new(), PlanKind::PerConstraint)
    }

    /// Clustered colouring for few sweeps (SPEC §9.3, beyond the thesis):
    ///
    /// - a *vertex unit* per particle: its single-particle constraints
    ///   (Attach, BranchAttach, Hard, Soft, Sliding) in `order`; they share
    ///   only that particle, so every vertex unit fits in one colour;
    /// - a *star unit* per internal point: every Internal constraint tying a
    ///   surface vertex to it (a surface vertex has one internal point, so
    ///   the stars are disjoint too) — the high-degree internal points no
    ///   longer need one colour per link;
    /// - every Branch and Fiber constraint alone (an edge colouring: Branch
    ///   joins internal points, Fiber surface vertices, so they share colours).
    ///
    /// Units are coloured greedily in that class order (vertex units, stars
    /// with the most links first, then the edges in creation order).
    pub fn clustered(m: &Muscle, order: &[ConstraintKind]) -> Self {
        let surface = ParticleId::from_index(m.surface_count);
        let mut vertex_units: Vec<Vec<ConstraintRef>> = vec![Vec::new(); m.x.len()];
        let mut stars: Vec<Vec<ConstraintRef>> = vec![Vec::new(); m.x.len()];
        let mut edges = Vec::new();
        for c in constraints_in_order(m, order) {
            match (c.kind, particles_of(m, c)) {
                (ConstraintKind::Internal, [Some(a), Some(b), None]) => {
                    let center = if a >= surface { a } else { b };
                    stars[center.index()].push(c);
                }
                (_, [Some(p), None, None]) => vertex_units[p.index()].push(c),
                _ => edges.push(vec![c]),
            }
        }
        let mut units: Vec<Vec<ConstraintRef>> = Vec::new();
        units.extend(vertex_units.into_iter().filter(|u| !u.is_empty()));
        let mut stars: Vec<_> = stars.into_iter().filter(|u| !u.is_empty()).collect();
        stars.sort_by_key(|u| std::cmp::Reverse(u.len()));
        units.extend(stars);
        units.extend(edges);
        let colors = greedy_units(m, &units)
            .into_iter()
            .map(|color| color.into_iter().map(|u| units[u].clone()).collect())
            .collect();
        Self::new(m, order, colors, Vec::new(), PlanKind::Clustered)
    }

    /// Hybrid (Fratarcangeli & Pellacini 2015): the thesis' per-constraint
    /// colours with at least `min_group` constraints are solved Gauss–Seidel;
    /// the constraints of the small, high-degree tail are solved together by
    /// one Jacobi pass after them (its single-particle constraints, if any,
    /// Gauss–Seidel just before it).
    pub fn hybrid(m: &Muscle, order: &[ConstraintKind], min_group: usize) -> Self {
        let groups = ColorGroups::greedy(m, order).groups;
        let (big, small): (Vec<_>, Vec<_>) = groups.into_iter().partition(|g| g.len() >= min_group);
        let colors = big
            .into_iter()
            .map(|g| g.into_iter().map(|c| vec![c]).collect())
            .collect();
        let tail = small.concat();
        Self::new(
            m,
            order,
            colors,
            tail,
            PlanKind::Hybrid {
                min_group: min_group as u32,
            },
        )
    }

    /// Checks and packs a colouring. Panics when a colour's units share a
    /// particle or a constraint is missing or repeated: that is a bug in the
    /// builder, and the parallel sweep must never see it.
    fn new(
        m: &Muscle,
        order: &[ConstraintKind],
        colors: Vec<Vec<Vec<ConstraintRef>>>,
        tail: Vec<ConstraintRef>,
        kind: PlanKind,
    ) -> Self {
        let counts = m.counts();
        let particles = m.x.len();
        let mut seen: Vec<Vec<bool>> = ConstraintKind::CANONICAL_ORDER
            .iter()
            .map(|&k| match k {
                ConstraintKind::Volume => Vec::new(),
                k => vec![false; counts.get(k)],
            })
            .collect();
        let mut mark = |c: ConstraintRef| {
            assert!(c.kind != ConstraintKind::Volume, "Volume is solved apart");
            let slot = &mut seen[c.kind as usize][c.index as usize];
            assert!(!*slot, "constraint {c:?} planned twice");
            *slot = true;
        };
        // owner[p]: the last unit (global index + 1) that moved p, and its colour.
        let mut owner: Vec<(u32, u32)> = vec![(0, u32::MAX); particles];
        let mut chunk_colors = vec![0u32];
        let mut plan = Self {
            refs: Vec::new(),
            sweep: SweepPlan::default(),
            tied: index_arrays(m).flatten().copied().collect(),
            off: off_flags(m).collect(),
            units: vec![0],
            colors: vec![0],
            chunks: vec![0],
            tail: None,
            kind,
            particles,
            counts,
        };
        for (ci, color) in colors.into_iter().enumerate() {
            let mut chunk_size = 0;
            for unit in color {
                let u = plan.units.len() as u32;
                for &c in &unit {
                    mark(c);
                    for p in particles_of(m, c).into_iter().flatten() {
                        let o = &mut owner[p.index()];
                        assert!(
                            o.1 != ci as u32 || o.0 == u,
                            "colour {ci} moves particle {p} from two units"
                        );
                        *o = (u, ci as u32);
                    }
                    plan.refs.push(c);
                }
                chunk_size += unit.len();
                plan.units.push(plan.refs.len() as u32);
                if chunk_size >= CHUNK_CONSTRAINTS {
                    plan.chunks.push(plan.units.len() as u32 - 1);
                    chunk_size = 0;
                }
            }
            if chunk_size > 0 {
                plan.chunks.push(plan.units.len() as u32 - 1);
            }
            plan.colors.push(plan.units.len() as u32 - 1);
            chunk_colors.push(plan.chunks.len() as u32 - 1);
        }
        for &c in &tail {
            mark(c);
        }
        let missing = seen.iter().position(|kind| kind.contains(&false));
        assert!(
            missing.is_none(),
            "{kind:?}: a constraint of type {missing:?} is not planned"
        );
        if !tail.is_empty() {
            // The tail's single-particle constraints are solved Gauss–Seidel
            // before its Jacobi pass, as in `Jacobi` (see `jacobi`).
            let (gauss_seidel, jacobi) = tail
                .into_iter()
                .partition(|c| super::jacobi::single_particle(m, c.kind));
            plan.tail = Some(JacobiState::from_parts(m, gauss_seidel, jacobi));
        }
        plan.sweep = plan.pack_segments(m, order, chunk_colors);
        plan
    }

    /// Splits every chunk into runs of one constraint type, in `order`'s
    /// type order. The units of a colour share no particle, so only each
    /// unit's own order matters, and it is kept: units are built type by
    /// type in `order` (checked), and the sort is stable. The runs need no
    /// per-constraint type dispatch, and the result is bit-identical to
    /// solving unit after unit. Switched-off constraints (weight 0: T7's
    /// Soft and Hard, a third of its constraints) are left out of the runs;
    /// they would return no correction.
    fn pack_segments(
        &self,
        m: &Muscle,
        order: &[ConstraintKind],
        chunk_colors: Vec<u32>,
    ) -> SweepPlan {
        let rank = |k: ConstraintKind| order.iter().position(|&o| o == k).unwrap_or(order.len());
        for u in 0..self.units.len() - 1 {
            let unit = self.unit(u);
            assert!(
                unit.windows(2).all(|w| rank(w[0].kind) <= rank(w[1].kind)),
                "unit {u} is not in the projection order's type order"
            );
        }
        let (mut ops, mut segments, mut chunk_segments) = (Vec::new(), Vec::new(), vec![0]);
        let mut chunk = Vec::new();
        for g in 0..self.chunks.len() - 1 {
            let (u0, u1) = (self.chunks[g] as usize, self.chunks[g + 1] as usize);
            chunk.clear();
            chunk.extend_from_slice(&self.refs[self.units[u0] as usize..self.units[u1] as usize]);
            chunk.sort_by_key(|c| rank(c.kind));
            let first = segments.len();
            // A switched-off constraint does nothing: the sweeps skip it.
            for c in chunk.iter().filter(|&&c| !is_off(m, c)) {
                let start = ops.len() as u32;
                ops.push(PlannedConstraint {
                    index: c.index,
                    particles: batch_particles(m, *c),
                });
                match segments[first..].last_mut() {
                    Some(Segment { kind, end, .. }) if *kind == c.kind => *end += 1,
                    _ => segments.push(Segment {
                        kind: c.kind,
                        start,
                        end: start + 1,
                    }),
                }
            }
            chunk_segments.push(segments.len() as u32);
        }
        SweepPlan::new(
            ops,
            segments,
            chunk_segments,
            chunk_colors,
            self.particles,
            self.counts,
        )
    }

    /// How the plan was built.
    pub fn kind(&self) -> PlanKind {
        self.kind
    }

    /// Whether the plan still matches `m`: the same particle and constraint
    /// counts, every planned constraint still moves the particles it moved
    /// when the plan was built, and the same constraints are switched off
    /// (weight 0). A compare of the index arrays against
    /// the plan's copy (about 0.1 ms per iteration on the full body, so the
    /// solver checks it in the first iteration of a substep, when a host may
    /// have edited the muscle, and rebuilds a stale plan). A stale plan would
    /// solve the old topology, never race: sweeps write only the particles
    /// the plan holds.
    pub fn fits(&self, m: &Muscle) -> bool {
        let mut rest = self.tied.as_slice();
        self.sized_for(m)
            && index_arrays(m).all(|now| {
                let Some((then, after)) = rest.split_at_checked(now.len()) else {
                    return false;
                };
                rest = after;
                then == now
            })
            && rest.is_empty()
            && off_flags_match(m, &self.off)
    }

    /// The cheap part of [`ColorPlan::fits`]: counts only.
    pub(super) fn sized_for(&self, m: &Muscle) -> bool {
        self.particles == m.x.len() && self.counts == m.counts()
    }

    /// Number of colours (parallel sweeps per iteration, the Jacobi tail apart).
    pub fn color_count(&self) -> usize {
        self.colors.len() - 1
    }

    /// Constraints per colour, in solve order.
    pub fn color_sizes(&self) -> Vec<usize> {
        (0..self.color_count())
            .map(|c| {
                let (a, b) = (self.colors[c] as usize, self.colors[c + 1] as usize);
                (self.units[b] - self.units[a]) as usize
            })
            .collect()
    }

    /// The units of colour `c`, each a run of constraints solved in order.
    pub fn units_of(&self, c: usize) -> impl Iterator<Item = &[ConstraintRef]> + '_ {
        (self.colors[c] as usize..self.colors[c + 1] as usize).map(move |u| self.unit(u))
    }

    /// The constraints of unit `u`, in solve order.
    pub(super) fn unit(&self, u: usize) -> &[ConstraintRef] {
        &self.refs[self.units[u] as usize..self.units[u + 1] as usize]
    }

    /// Number of chunks of colour `c`.
    pub fn chunk_count(&self, c: usize) -> usize {
        self.sweep.chunk_count(c)
    }

    /// What the colour sweeps run.
    pub(super) fn sweep(&self) -> &SweepPlan {
        &self.sweep
    }

    /// Runs the Jacobi tail of the plan on `m`, if it has one (Hybrid).
    pub(super) fn project_tail(&mut self, m: &mut Muscle, inv_h2: f32, omega: f32, split: bool) {
        if let Some(tail) = &mut self.tail {
            super::jacobi::project_jacobi(m, tail, inv_h2, omega, split);
        }
    }

    /// The constraints solved Jacobi after the colours (Hybrid), if any.
    pub fn tail(&self) -> &[ConstraintRef] {
        self.tail.as_ref().map_or(&[], |t| &t.jacobi)
    }
}

#[cfg(test)]
mod tests;
