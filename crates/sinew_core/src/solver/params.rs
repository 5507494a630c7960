//! What each level of the frame loop needs from the settings, computed once
//! and read by name: [`FrameParams`] per step, [`SubstepParams`] per
//! substep, [`IterationParams`] per iteration. Every driver (the plain
//! [`super::Solver`], the Bevy systems) builds them the same way, from
//! validated settings, so a setting means the same in all of them.

use super::settings::{SolverMethod, SolverSettings, SweepSchedule};
use crate::constraints::VolumeProjection;
use crate::muscle::ConstraintKind;
use crate::muscle::Muscle;
use glam::Vec3;

/// The projection order of a step, held by value (at most one entry per
/// constraint type).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ProjectionOrder {
    kinds: [ConstraintKind; ConstraintKind::COUNT],
    len: u8,
}

impl ProjectionOrder {
    /// The first [`ConstraintKind::COUNT`] entries of `order` (a valid
    /// order lists every type once: `SolverSettings::validate`).
    pub fn new(order: &[ConstraintKind]) -> Self {
        let mut kinds = ConstraintKind::CANONICAL_ORDER;
        let len = order.len().min(kinds.len());
        kinds[..len].copy_from_slice(&order[..len]);
        Self {
            kinds,
            len: len as u8,
        }
    }

    /// The order as a slice.
    pub fn as_slice(&self) -> &[ConstraintKind] {
        &self.kinds[..self.len as usize]
    }
}

/// Which vertices run the full closest-point search, choose their target or
/// walk in an iteration (see [`crate::closest`] and the settings of the same
/// names).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestSchedule {
    /// Frame counter (staggers the vertices).
    pub frame: u64,
    /// Frames between two full searches of one vertex.
    pub interval: u32,
    /// Frames between two choices of a vertex's target (a vertex with a
    /// full search also chooses).
    pub choose_interval: u32,
    /// Without `walk`, project onto the feature the walk found.
    pub feature_contacts: bool,
    /// The first iteration of a frame: full searches run, and vertices
    /// re-choose their target (one in `choose_interval`).
    pub first_of_frame: bool,
    /// Walk from the last triangle (else re-project onto it).
    pub walk: bool,
    /// The first iteration of a substep: bones have just been posed.
    pub first_of_substep: bool,
    /// Split the vertices over the current rayon pool (same result).
    pub split: bool,
}

impl ClosestSchedule {
    /// Every vertex, every target: the full search.
    #[cfg(test)]
    pub const ALWAYS: Self = Self {
        frame: 0,
        interval: 1,
        choose_interval: 1,
        feature_contacts: false,
        first_of_frame: true,
        walk: true,
        first_of_substep: true,
        split: false,
    };

    /// Whether vertex `vertex` runs the full search now.
    pub(super) fn wants(&self, vertex: usize) -> bool {
        self.first_of_frame && (vertex as u64 + self.frame).is_multiple_of(self.interval as u64)
    }

    /// Whether vertex `vertex` re-chooses its target now.
    pub(super) fn chooses(&self, vertex: usize) -> bool {
        self.first_of_frame
            && (vertex as u64 + self.frame).is_multiple_of(self.choose_interval as u64)
            || self.wants(vertex)
    }
}

/// How a step spreads its work over the driver's threads. The same bits
/// whatever it says; it only decides where a fork and join pays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Parallelism {
    /// Muscle passes (closest data, projection) run muscle by muscle on the
    /// pool, and a large muscle splits its own work into chunks.
    pub muscles: bool,
    /// Per-particle passes (integration, goals, publishing) run on the pool.
    pub particles: bool,
}

impl Parallelism {
    /// How many bare particles' work each particle of a muscle with a held
    /// line ([`crate::muscle::HoldLine`]) counts for in the per-particle
    /// passes: its goals come from the line in every substep. Measured on
    /// T5's begin-substep pass on one thread: 37 ns a particle with the
    /// line (49 where the rest lengths follow it too) against 9 with the
    /// bones' blend, 7 on T7. Counting them bare kept T5's 3,009 particles
    /// (≈ 0.14 ms a frame in that pass) on one thread at any thread count.
    pub const HELD_LINE_WEIGHT: usize = 4;

    /// The split for a scene of `muscles`, given whether the driver has
    /// worker threads: [`SolverSettings::parallel_threshold`] (compared with
    /// the scene's constraint count, and with its particle count where a
    /// particle of a muscle with a held line counts
    /// [`Parallelism::HELD_LINE_WEIGHT`] times) keeps small scenes on the
    /// calling thread.
    pub fn decide<'a>(
        settings: &SolverSettings,
        threads: bool,
        muscles: impl IntoIterator<Item = &'a Muscle>,
    ) -> Self {
        let weight = |m: &Muscle| match m.hold_line {
            Some(_) => Self::HELD_LINE_WEIGHT,
            None => 1,
        };
        let (constraints, particles) = muscles.into_iter().fold((0, 0), |(c, p), m| {
            (c + m.counts().total(), p + m.x.len() * weight(m))
        });
        Self {
            muscles: threads && constraints >= settings.parallel_threshold,
            particles: threads && particles >= settings.parallel_threshold,
        }
    }
}

/// A step's parameters, from validated settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameParams {
    /// Frames stepped before this one.
    pub frame: u64,
    /// Simulated time the step covers, `dt × time_scale`. Units: s.
    pub dt: f32,
    /// Substeps.
    pub substeps: u32,
    /// The global iteration count `N`; a muscle runs its own count.
    pub iterations: u32,
    /// Gravity in scene units, `g × length_unit`. Units: scene units/s².
    pub gravity: Vec3,
    /// Projection method.
    pub method: SolverMethod,
    /// Projection order.
    pub order: ProjectionOrder,
    /// Frames between full closest-point searches.
    pub full_search_interval: u32,
    /// Frames between target choices.
    pub choose_interval: u32,
    /// Project onto walk features in the iterations that do not walk.
    pub feature_contacts: bool,
    /// Iterations between Sliding's walks.
    pub walk_interval: u32,
    /// Iterations between bone contacts.
    pub bone_contact_interval: u32,
    /// Iterations between publications of the muscles' snapshots: the
    /// length of a block of iterations each muscle runs in one task.
    pub snapshot_interval: u32,
    /// How coloured methods use the threads.
    pub schedule: SweepSchedule,
    /// Worker threads (`0`: every core, `1`: the calling thread only).
    pub threads: u32,
    /// Where the work runs.
    pub parallelism: Parallelism,
}

impl FrameParams {
    /// The parameters of frame `frame` (0-based) with `settings`, which must
    /// have passed [`SolverSettings::validate`].
    pub fn new(settings: &SolverSettings, frame: u64, parallelism: Parallelism) -> Self {
        let substeps = settings.substeps.max(1);
        Self {
            frame,
            dt: settings.step_time(),
            substeps,
            iterations: settings.iterations.max(1),
            gravity: settings.gravity * settings.length_unit,
            method: settings.method,
            order: ProjectionOrder::new(&settings.projection_order),
            full_search_interval: settings.full_search_interval.max(1),
            choose_interval: settings.choose_interval.max(1),
            feature_contacts: settings.feature_contacts,
            walk_interval: settings.walk_interval.max(1),
            bone_contact_interval: settings.bone_contact_interval.max(1),
            snapshot_interval: settings.snapshot_interval.max(1),
            schedule: settings.schedule,
            threads: settings.threads,
            parallelism,
        }
    }

    /// Iterations the loop runs: the global count, or a muscle's own if any
    /// is larger.
    pub fn iterations_for<'a>(&self, muscles: impl IntoIterator<Item = &'a Muscle>) -> u32 {
        muscles
            .into_iter()
            .map(|m| self.iterations_of(m))
            .fold(self.iterations, u32::max)
    }

    /// The iterations `m` runs in a substep: its own count or the global.
    pub fn iterations_of(&self, m: &Muscle) -> u32 {
        m.params.iterations.unwrap_or(self.iterations)
    }

    /// Substep `index` (0-based).
    pub fn substep(&self, index: u32) -> SubstepParams {
        let h = self.dt / self.substeps as f32;
        SubstepParams {
            frame: *self,
            index,
            alpha: (index + 1) as f32 / self.substeps as f32,
            h,
            inv_h2: 1.0 / (h * h),
        }
    }
}

/// A substep's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SubstepParams {
    /// The step's.
    pub frame: FrameParams,
    /// Substep index (0-based).
    pub index: u32,
    /// Fraction of the frame reached at the substep's end.
    pub alpha: f32,
    /// Substep length. Units: s.
    pub h: f32,
    /// `1 / h²`.
    pub inv_h2: f32,
}

impl SubstepParams {
    /// Iteration `index` (0-based) of the `count` this substep runs.
    pub fn iteration(&self, index: u32, count: u32) -> IterationParams {
        IterationParams {
            substep: *self,
            index,
            count,
        }
    }

    /// The first iteration of each block of the `count` this substep runs
    /// ([`IterationParams::block`]), in order: what a driver publishes the
    /// snapshots before and runs a block from.
    pub fn blocks(&self, count: u32) -> impl Iterator<Item = IterationParams> + use<> {
        let first = (count > 0).then(|| self.iteration(0, count));
        std::iter::successors(first, move |b| {
            let next = b.block_end();
            (next < count).then(|| b.at(next))
        })
    }
}

/// An iteration's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IterationParams {
    /// The substep's.
    pub substep: SubstepParams,
    /// Iteration index within the substep (0-based).
    pub index: u32,
    /// Iterations the substep runs: the largest of the muscles' counts
    /// ([`FrameParams::iterations_for`]).
    pub count: u32,
}

impl IterationParams {
    /// The first iteration of the frame: full closest-point searches, target
    /// choices, snapshot normals and refits.
    pub fn first_of_frame(&self) -> bool {
        self.index == 0 && self.substep.index == 0
    }

    /// The first iteration of the substep: bones were just posed, plans are
    /// checked against their muscles.
    pub fn first_of_substep(&self) -> bool {
        self.index == 0
    }

    /// One past the last iteration of the block this one starts
    /// ([`SolverSettings::snapshot_interval`] iterations, fewer at the
    /// substep's end): the snapshots published before this iteration are
    /// read until then, and the next block starts there.
    pub fn block_end(&self) -> u32 {
        let interval = self.substep.frame.snapshot_interval.max(1);
        self.index.saturating_add(interval).min(self.count)
    }

    /// Iteration `index` of the same substep.
    pub fn at(&self, index: u32) -> Self {
        Self { index, ..*self }
    }

    /// The iterations of the block this one starts, in order (itself first).
    pub fn block(&self) -> impl Iterator<Item = Self> + use<> {
        let this = *self;
        (self.index..self.block_end()).map(move |k| this.at(k))
    }

    /// Whether `m` stages its snapshot after this iteration of the block
    /// ending at `block_end` (the [`IterationParams::block_end`] of the
    /// iteration that started it): after `m`'s last iteration in the block
    /// — the block's last, or `m`'s own last where its count ends inside
    /// the block, or the last of a surface layer's spread iterations
    /// there ([`IterationParams::runs`]) — what it leaves then is what the
    /// next block's snapshot publishes.
    pub fn stages_for(&self, m: &Muscle, block_end: u32) -> bool {
        self.own(m).next_after(self.index) >= block_end
    }

    /// The substep's last iteration: no iteration of the substep comes
    /// after it to read a snapshot staged in it.
    pub fn last_of_substep(&self) -> bool {
        self.index + 1 >= self.count
    }

    /// Whether `m` runs this iteration. A muscle runs its own count's
    /// first iterations (`index <` its count: the thesis' rule); a surface
    /// layer (a skin) with fewer iterations than the substep spreads them
    /// evenly over it (its `j`-th at `⌈j · count / own⌉`: 4 of 10 run at
    /// 0, 3, 5 and 8): its later ones read the muscles under it further on
    /// in their convergence, and in blocks of iterations
    /// ([`crate::SolverSettings::snapshot_interval`]) its work is shared
    /// between the blocks, beside the muscles'.
    pub fn runs(&self, m: &Muscle) -> bool {
        self.own(m).runs(self.index)
    }

    /// Whether `m`'s bone contacts run this iteration: in the substep's
    /// first, every [`SolverSettings::bone_contact_interval`]-th after it
    /// and `m`'s last; a surface layer's (a skin: few iterations, and
    /// Sliding's walk only in the first) in every one it runs.
    pub fn contacts_bones(&self, m: &Muscle) -> bool {
        let every = match m.params.is_surface_layer() {
            true => 1,
            false => self.substep.frame.bone_contact_interval,
        };
        self.index.is_multiple_of(every) || self.last_for(m)
    }

    /// Whether this is `m`'s last iteration of the substep (its own count
    /// reached after it).
    pub fn last_for(&self, m: &Muscle) -> bool {
        let own = self.own(m);
        own.runs(self.index) && own.next_after(self.index) == u32::MAX
    }

    /// Which iterations of this substep `m` runs.
    fn own(&self, m: &Muscle) -> OwnIterations {
        let own = self.substep.frame.iterations_of(m).min(self.count);
        OwnIterations {
            own,
            count: self.count,
            // A count of 0 (refused by validation, but a host may set it
            // between steps) runs nothing, spread or not.
            spread: own > 0 && own < self.count && m.params.is_surface_layer(),
        }
    }

    /// How far `m`'s Volume is projected this iteration: one linearised step
    /// while iterations follow, to convergence in `m`'s last (see
    /// [`VolumeProjection`]).
    pub fn volume_projection(&self, m: &Muscle) -> VolumeProjection {
        match self.last_for(m) {
            true => VolumeProjection::Converge,
            false => VolumeProjection::Step,
        }
    }

    /// Closest data's schedule for this iteration.
    pub fn closest(&self) -> ClosestSchedule {
        let f = &self.substep.frame;
        ClosestSchedule {
            frame: f.frame,
            interval: f.full_search_interval,
            choose_interval: f.choose_interval,
            feature_contacts: f.feature_contacts,
            first_of_frame: self.first_of_frame(),
            walk: self.index.is_multiple_of(f.walk_interval),
            first_of_substep: self.first_of_substep(),
            split: f.parallelism.muscles,
        }
    }
}

/// The iterations one muscle runs in a substep of `count`
/// ([`IterationParams::runs`]): its first `own`, or with `spread` its
/// `j`-th at `⌈j · count / own⌉` for `j < own`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct OwnIterations {
    own: u32,
    count: u32,
    spread: bool,
}

impl OwnIterations {
    /// The substep's iteration index of the muscle's own iteration `j`.
    fn index_of(&self, j: u32) -> u32 {
        match self.spread {
            true => (u64::from(j) * u64::from(self.count)).div_ceil(u64::from(self.own)) as u32,
            false => j,
        }
    }

    /// How many of its own iterations the muscle has run before iteration
    /// `index` of the substep.
    fn before(&self, index: u32) -> u32 {
        match (self.spread, index) {
            (true, 0) => 0,
            // `j` runs at `⌈j · count / own⌉ ≤ index − 1` for every
            // `j ≤ (index − 1) · own / count`.
            (true, _) => {
                let last = u64::from(index - 1) * u64::from(self.own) / u64::from(self.count);
                (last as u32 + 1).min(self.own)
            }
            (false, _) => index.min(self.own),
        }
    }

    /// Whether the muscle runs iteration `index`.
    fn runs(&self, index: u32) -> bool {
        let j = self.before(index);
        j < self.own && self.index_of(j) == index
    }

    /// The next iteration after `index` that the muscle runs; `u32::MAX`
    /// when none does in the substep.
    fn next_after(&self, index: u32) -> u32 {
        let j = self.before(index.saturating_add(1));
        match j < self.own {
            true => self.index_of(j),
            false => u32::MAX,
        }
    }
}
