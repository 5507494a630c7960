//! Muscles of one topology in groups of [`LANES`], their distance
//! constraints and Volumes projected side by side
//! ([`DistanceLanes`](crate::constraints::DistanceLanes),
//! [`VolumeLanes`](crate::constraints::VolumeLanes)): the plain
//! Gauss–Seidel pass (`Sequential`) over muscles, with the same bits.
//!
//! A group is [`LANES`] neighbours in the driver's list whose distance
//! batches have the same index arrays (muscles swept from one recipe: all
//! 144 of T7's), that run the same iterations as plain Gauss–Seidel, and
//! that are not surface layers. One task runs a group's block of
//! iterations: in each iteration every member's closest data and its
//! constraints before the distance batches, the four members' distance
//! batches in lanes, then each member's constraints after them and its
//! bone contacts, the trailing Volumes in lanes (where the members'
//! surfaces share one topology; member by member otherwise), and each
//! member's staged snapshot. The members read one another only through
//! the snapshots published before the block, so running their phases
//! interleaved gives each the bits its own task gives. A group whose
//! members turn out not to share their index arrays (a host retied one by
//! hand) runs member by member; the group decides in each substep's first
//! iteration ([`LaneGroup`]).
//!
//! The muscles are shared out over the threads in ranges as they are
//! muscle by muscle (`super::muscle_ranges`), a range of the same size
//! for each thread ([`GroupShare`]): its thread runs the whole groups at
//! its front, then the muscles past them one by one; a thread out of work
//! takes the others' muscles from their backs, the lone ones first, then
//! whole groups. With fewer than [`GROUPS_PER_THREAD`] groups a thread,
//! or a muscle large enough to start first
//! ([`super::parallel::for_each_muscle`]), the pass runs muscle by muscle.

use super::bone_contacts::bone_contacts;
use super::muscle_ranges::{Share, for_each_in_ranges_as};
use super::parallel::{MusclePair, dominant, for_each_muscle};
use super::params::IterationParams;
use super::pipeline::{self, gauss_seidel_over, split_volume};
use super::settings::SolverMethod;
use super::timings::TaskSplit;
use crate::closest::TargetSet;
use crate::constraints::{
    DistanceBatch, DistanceLanes, LANES, ParticleId, VolumeLanes, volumes_share_topology,
};
use crate::muscle::{ConstraintKind, Muscle};

/// What the first muscle of a group keeps for it: whether the group runs
/// in lanes, decided in each substep's first iteration (a host edits
/// batches between steps, and both ways give the same bits), and the
/// lanes, whose storage is reused.
#[derive(Clone, Debug, Default)]
pub(crate) struct LaneGroup {
    /// The members share their distance index arrays and run alike.
    fits: bool,
    /// Their Volumes share one surface topology too.
    volumes_fit: bool,
    /// `distance` holds the members' inverse masses, rest lengths and
    /// multipliers, as the substep's first block took them: its later
    /// blocks go on with them. Between blocks only snapshots are
    /// published; the masses and rest lengths change at a substep's or a
    /// frame's start, and each block gives the multipliers back to the
    /// members as the lanes hold them (T7's second block of a frame took
    /// them all into lanes again).
    loaded: bool,
    distance: DistanceLanes,
    volume: VolumeLanes,
}

/// Groups a thread must have at least, for the pass to run by groups: a
/// group is four muscles' work, taken whole, and the muscles' costs differ
/// (their contacts). P4's 17 muscles on two threads (four groups and a
/// muscle) ran ×0.934 faster by groups in shares of a thread's size with
/// their lone muscles last (ten rounds of `scripts/ab_bench.py --threads
/// 2`; ×1.018 *slower* when the groups were shared out in ranges of equal
/// group counts, the lone muscle in the last group's task); T7's 144, 36
/// groups, ×0.91 faster (five pairs).
const GROUPS_PER_THREAD: usize = 2;

/// Whether `kind` is projected by a [`DistanceBatch`].
fn is_distance(kind: ConstraintKind) -> bool {
    matches!(
        kind,
        ConstraintKind::Fiber | ConstraintKind::Branch | ConstraintKind::Internal
    )
}

/// The order split around its first run of distance kinds: `(before, the
/// run, after)`; `None` without one.
fn around_distance_run(
    order: &[ConstraintKind],
) -> Option<(&[ConstraintKind], &[ConstraintKind], &[ConstraintKind])> {
    let start = order.iter().position(|&k| is_distance(k))?;
    let len = order[start..]
        .iter()
        .take_while(|&&k| is_distance(k))
        .count();
    let (before, rest) = order.split_at(start);
    let (run, after) = rest.split_at(len);
    // Each kind once: a batch projected twice keeps one multiplier array.
    let distinct = run.iter().enumerate().all(|(i, k)| !run[..i].contains(k));
    distinct.then_some((before, run, after))
}

/// `m`'s distance batches of the kinds in `run`, in that order.
fn distance_batches<'m>(m: &'m Muscle, run: &[ConstraintKind]) -> [&'m DistanceBatch; 3] {
    let c = &m.constraints;
    let of = |k: usize| match run.get(k) {
        Some(ConstraintKind::Branch) => &c.branch,
        Some(ConstraintKind::Internal) => &c.internal,
        _ => &c.fiber,
    };
    [of(0), of(1), of(2)]
}

/// Whether `m` can be a group member under `it`: plain Gauss–Seidel, not
/// a surface layer.
fn member_fits(m: &Muscle, it: &IterationParams) -> bool {
    let f = &it.substep.frame;
    !m.params.is_surface_layer() && pipeline::plan_kind_of(m, f.method).is_none()
}

/// Whether the members of `group` run together: each fits, runs the
/// iterations the first runs, and has the first's particles and distance
/// index arrays for the kinds of `run`.
fn runs_in_lanes(
    group: &[MusclePair; LANES],
    it: &IterationParams,
    run: &[ConstraintKind],
) -> bool {
    let first = &*group[0].0;
    let f = &it.substep.frame;
    let iterations = f.iterations_of(first);
    let same_arrays = |m: &Muscle| {
        let (a, b) = (distance_batches(first, run), distance_batches(m, run));
        a.iter()
            .zip(&b)
            .all(|(a, b)| same_particles(&a.a, &b.a) && same_particles(&a.b, &b.b))
    };
    group.iter().all(|(m, _)| {
        member_fits(m, it)
            && f.iterations_of(m) == iterations
            && m.p.len() == first.p.len()
            && m.w.len() == first.w.len()
            && same_arrays(m)
    })
}

/// Whether two index arrays are equal. A slice of a newtype compares
/// element by element, one branch each (only bare integers get a memory
/// compare); this folds 64 indices at a time without a branch, which
/// compiles to vector code: every group's arrays are compared in each
/// frame's first iteration (T7: 1.9 % of its run's samples with `==`).
fn same_particles(a: &[ParticleId], b: &[ParticleId]) -> bool {
    const BLOCK: usize = 64;
    a.len() == b.len()
        && (a.chunks(BLOCK).zip(b.chunks(BLOCK)))
            .all(|(a, b)| a.iter().zip(b).fold(0, |d, (x, y)| d | (x.raw() ^ y.raw())) == 0)
}

/// The block of iterations `it` starts, for a group of muscles with their
/// distance batches in lanes (module docs); member by member where they
/// do not share them.
fn iterate_group<T: TargetSet + Sync + ?Sized>(
    group: &mut [MusclePair; LANES],
    targets: &T,
    it: &IterationParams,
    timer: &TaskSplit,
) {
    let f = &it.substep.frame;
    let (order, trailing) = split_volume(f.order.as_slice());
    let mut state = std::mem::take(&mut group[0].1.lane_group);
    let split = around_distance_run(order);
    if let Some((_, run, _)) = split.filter(|_| it.first_of_substep()) {
        state.fits = runs_in_lanes(group, it, run);
        state.loaded = false;
        let volumes = group.each_ref().map(|(m, _)| m.constraints.volume.as_ref());
        state.volumes_fit = match volumes {
            [Some(a), Some(b), Some(c), Some(d)] => volumes_share_topology([a, b, c, d]),
            _ => false,
        };
    }
    let Some((before, run, after)) = split.filter(|_| state.fits) else {
        group[0].1.lane_group = state;
        for (m, ws) in group.iter_mut() {
            pipeline::iterate(m, ws, targets, it, timer);
        }
        return;
    };
    let inv_h2 = it.substep.inv_h2;
    let split_muscles = f.parallelism.muscles;
    if !state.loaded {
        let batches = group.each_ref().map(|(m, _)| distance_batches(m, run));
        let slices = batches.each_ref().map(|b| &b[..run.len()]);
        let w = group.each_ref().map(|(m, _)| m.w.as_slice());
        state.distance.load_batches(w, slices);
        state.loaded = true;
    }
    let end = it.block_end();
    for it in it.block() {
        if !it.runs(&*group[0].0) {
            continue;
        }
        let start = timer.start();
        for (m, ws) in group.iter_mut() {
            pipeline::closest_data(m, ws, targets, it.closest());
        }
        let middle = timer.lap(start, 0);
        for (m, ws) in group.iter_mut() {
            let volume = it.volume_projection(m);
            gauss_seidel_over(m, before, inv_h2, Some(&ws.switched_on), volume);
        }
        let lanes = &mut state.distance;
        lanes.load_positions(group.each_ref().map(|(m, _)| m.p.as_slice()));
        lanes.solve(&distance_batches(group[0].0, run)[..run.len()], inv_h2);
        let [a, b, c, d] = &mut *group;
        lanes.store_positions([&mut a.0.p, &mut b.0.p, &mut c.0.p, &mut d.0.p]);
        // Each member's constraints after the distance batches and its
        // bone contacts, then the trailing Volumes, in lanes where their
        // surfaces share one topology ([`pipeline::finish`] for plain
        // Gauss–Seidel).
        for (m, ws) in group.iter_mut() {
            let volume = it.volume_projection(m);
            gauss_seidel_over(m, after, inv_h2, Some(&ws.switched_on), volume);
            if it.contacts_bones(m) {
                bone_contacts(m, ws, targets, it.first_of_substep(), split_muscles);
            }
        }
        if trailing && state.volumes_fit {
            let how = group.each_ref().map(|(m, _)| it.volume_projection(m));
            let [a, b, c, d] = &mut *group;
            let members = [&mut *a.0, &mut *b.0, &mut *c.0, &mut *d.0].map(|m| {
                let volume = m.constraints.volume.as_mut().expect("checked");
                (volume, &mut m.p[..], &m.w[..])
            });
            state.volume.solve(members, inv_h2, how);
        } else if trailing {
            for (m, _) in group.iter_mut() {
                pipeline::project_volume(m, &it, inv_h2, split_muscles);
            }
        }
        for (m, ws) in group.iter_mut() {
            if it.stages_for(m, end) {
                pipeline::stage_snapshot(m, ws, targets, &it);
            }
        }
        timer.lap(middle, 1);
    }
    for (lane, (m, _)) in group.iter_mut().enumerate() {
        for (batch, &kind) in run.iter().enumerate() {
            if let Some(b) = m.constraints.batch_mut(kind) {
                state.distance.store_lambdas(lane, batch, b.lambdas_mut());
            }
        }
    }
    group[0].1.lane_group = state;
}

/// Closest data and projection of every muscle for the block of
/// iterations `it` starts, one task per muscle or per group of muscles
/// of one topology (module docs), on `pool` when given.
pub(super) fn iterate_by_muscle<T: TargetSet + Sync + ?Sized>(
    pool: Option<&rayon::ThreadPool>,
    muscles: &mut [MusclePair],
    targets: &T,
    it: &IterationParams,
    timer: &TaskSplit,
) {
    let threads = pool.map_or(1, |p| p.current_num_threads());
    let order = it.substep.frame.order.as_slice();
    let groups_pay = it.substep.frame.method == SolverMethod::Sequential
        && around_distance_run(split_volume(order).0).is_some()
        && muscles.len() / LANES >= GROUPS_PER_THREAD * threads.max(1)
        && dominant(muscles, threads).is_none();
    if !groups_pay {
        for_each_muscle(pool, muscles, |m, ws| {
            pipeline::iterate(m, ws, targets, it, timer)
        });
        return;
    }
    let run = |task: Task<MusclePair>| match task {
        Task::Group(group) => iterate_group(group, targets, it, timer),
        Task::Muscle((m, ws)) => pipeline::iterate(m, ws, targets, it, timer),
    };
    match pool {
        // A share of the same size for each thread, as muscle by muscle:
        // its groups stay on the thread block after block.
        Some(pool) => pool.install(|| {
            let share = |_, muscles| GroupShare::of(muscles);
            for_each_in_ranges_as(muscles, threads, share, &run);
        }),
        None => {
            let mut share = GroupShare::of(muscles);
            while let Some(task) = share.front() {
                run(task);
            }
        }
    }
}

/// A task of a pass by groups: a group of muscles in lanes, or a muscle
/// on its own.
#[derive(Debug, PartialEq)]
enum Task<'a, T> {
    Group(&'a mut [T; LANES]),
    Muscle(&'a mut T),
}

/// A thread's share of the muscles in a pass by groups: as many whole
/// groups from its front as it holds, then its last muscles one by one
/// (fewer than [`LANES`]), which a thread out of work takes first from
/// its back.
struct GroupShare<'a, T> {
    muscles: &'a mut [T],
    /// Whole groups left at the front of `muscles`.
    groups: usize,
}

impl<T> Default for GroupShare<'_, T> {
    fn default() -> Self {
        Self {
            muscles: &mut [],
            groups: 0,
        }
    }
}

impl<'a, T> GroupShare<'a, T> {
    /// `muscles` as a share.
    fn of(muscles: &'a mut [T]) -> Self {
        let groups = muscles.len() / LANES;
        Self { muscles, groups }
    }
}

impl<'a, T: Send> Share for GroupShare<'a, T> {
    type Item = Task<'a, T>;

    fn front(&mut self) -> Option<Task<'a, T>> {
        let muscles = std::mem::take(&mut self.muscles);
        if self.groups > 0 {
            let (group, rest) = muscles.split_first_chunk_mut::<LANES>()?;
            (self.muscles, self.groups) = (rest, self.groups - 1);
            Some(Task::Group(group))
        } else {
            let (muscle, rest) = muscles.split_first_mut()?;
            self.muscles = rest;
            Some(Task::Muscle(muscle))
        }
    }

    fn back(&mut self) -> Option<Task<'a, T>> {
        let muscles = std::mem::take(&mut self.muscles);
        if muscles.len() > self.groups * LANES {
            let (muscle, rest) = muscles.split_last_mut()?;
            self.muscles = rest;
            Some(Task::Muscle(muscle))
        } else {
            let (rest, group) = muscles.split_last_chunk_mut::<LANES>()?;
            (self.muscles, self.groups) = (rest, self.groups - 1);
            Some(Task::Group(group))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::same_particles;
    use crate::constraints::ParticleId;

    use crate::scene::builtin;
    use crate::solver::Solver;
    use glam::Vec3;

    /// 21 copies of P1's oval (one topology) side by side, `threads`
    /// workers, after `edit` has changed the built solver.
    fn crowd(threads: u32, edit: impl FnOnce(&mut Solver)) -> Solver {
        let mut scene = builtin("P1")
            .unwrap()
            .crowd(21, Vec3::X * 0.3, 0.1)
            .unwrap();
        scene.settings.gravity = Vec3::new(0.0, -9.81, 0.0);
        scene.settings.threads = threads;
        scene.settings.parallel_threshold = 0;
        let mut s = scene.instantiate(std::path::Path::new(".")).unwrap();
        edit(&mut s);
        s
    }

    fn bits(s: &Solver) -> Vec<u32> {
        (s.muscles().iter())
            .flat_map(|m| m.x.iter().flat_map(|p| p.to_array().map(f32::to_bits)))
            .collect()
    }

    /// Equal index arrays, and arrays that differ at the first, a block's
    /// last, the next block's first and the last index, or in length;
    /// seen to fail with each block's last index left out.
    #[test]
    fn same_particles_tells_every_difference() {
        let ids =
            |n: u32| -> Vec<ParticleId> { (0..n).map(|i| ParticleId::new(i * 3 + 1)).collect() };
        let a = ids(130);
        assert!(same_particles(&a, &a.clone()));
        assert!(same_particles(&[], &[]));
        for at in [0, 63, 64, 129] {
            let mut b = a.clone();
            b[at] = ParticleId::new(b[at].raw() ^ 1 << 20);
            assert!(!same_particles(&a, &b), "differs at {at}");
        }
        assert!(!same_particles(&a, &a[..129]));
    }

    /// Whether a muscle led a group in lanes (its lanes hold particles).
    fn led_a_group(s: &Solver, m: usize) -> bool {
        s.workspaces()[m].lane_group.distance.particles() > 0
    }

    /// On one thread the 21 muscles run in five groups and the one past
    /// them alone; on two, in a share each of 11 and 10 muscles (two
    /// groups each, the muscles past them alone); on three, muscle by
    /// muscle (five groups are too few to share out). All give the same
    /// bits, every ten frames over sixty.
    #[test]
    fn groups_in_lanes_give_the_bits_of_muscle_by_muscle() {
        let mut solvers = [1, 2, 3].map(|threads| crowd(threads, |_| {}));
        for frame in 0..60 {
            for s in &mut solvers {
                s.step();
            }
            if frame % 10 == 9 {
                let [one, two, single] = &solvers;
                assert_eq!(bits(one), bits(single), "one thread, frame {frame}");
                assert_eq!(bits(two), bits(single), "two threads, frame {frame}");
            }
        }
        let [one, two, single] = &solvers;
        assert!(led_a_group(one, 0) && led_a_group(one, 16));
        assert!(!led_a_group(one, 1), "a group's first muscle leads it");
        assert!(
            !led_a_group(one, 20),
            "the muscle past the groups runs alone"
        );
        // Two shares: muscles 0–10 (groups at 0 and 4, 8–10 alone) and
        // 11–20 (groups at 11 and 15, 19–20 alone).
        let led: Vec<usize> = (0..21).filter(|&m| led_a_group(two, m)).collect();
        assert_eq!(led, [0, 4, 11, 15], "two threads: the groups of each share");
        assert!(!led_a_group(single, 0), "three threads: muscle by muscle");
    }

    /// A share's own thread takes its whole groups first and then its
    /// lone muscles; a thread out of work takes the lone muscles first
    /// (the last first), then the groups from the back; each muscle once.
    #[test]
    fn a_share_gives_its_groups_from_the_front_and_its_lone_muscles_from_the_back() {
        use super::{GroupShare, Share, Task};
        let indices = |task: Task<usize>| match task {
            Task::Group(g) => g.to_vec(),
            Task::Muscle(m) => vec![*m],
        };
        let mut muscles: Vec<usize> = (0..11).collect();
        let mut share = GroupShare::of(&mut muscles);
        assert_eq!(share.front().map(indices), Some(vec![0, 1, 2, 3]));
        assert_eq!(share.back().map(indices), Some(vec![10]));
        assert_eq!(share.back().map(indices), Some(vec![9]));
        assert_eq!(share.front().map(indices), Some(vec![4, 5, 6, 7]));
        assert_eq!(share.front().map(indices), Some(vec![8]));
        assert_eq!(share.front(), None);
        assert_eq!(share.back(), None);
        let mut muscles: Vec<usize> = (0..9).collect();
        let mut share = GroupShare::of(&mut muscles);
        let from_back: Vec<Vec<usize>> = std::iter::from_fn(|| share.back().map(indices)).collect();
        assert_eq!(from_back, [vec![8], vec![4, 5, 6, 7], vec![0, 1, 2, 3]]);
    }

    /// A group whose muscle was retied by hand (its batch edited without
    /// `touch_topology`) runs member by member: the retied muscle and its
    /// group keep the bits of muscle by muscle.
    #[test]
    fn a_group_of_retied_muscles_runs_muscle_by_muscle() {
        let retie = |s: &mut Solver| {
            let fiber = &mut s.muscle_mut(5).constraints.fiber;
            let (a, b) = (fiber.a[3], fiber.b[3]);
            (fiber.a[3], fiber.b[3]) = (b, a);
        };
        let (mut grouped, mut single) = (crowd(1, retie), crowd(3, retie));
        for _ in 0..20 {
            grouped.step();
            single.step();
        }
        assert_eq!(bits(&grouped), bits(&single));
        assert!(
            !led_a_group(&grouped, 4),
            "the retied muscle's group ran muscle by muscle"
        );
        assert!(led_a_group(&grouped, 0));
    }
}
