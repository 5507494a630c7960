//! The frame loop's per-muscle stages, shared by [`super::Solver`] and by
//! any other driver (the Bevy plug-in runs them from ECS systems).
//!
//! A substep of one muscle is:
//!
//! ```text
//! update_attachment_goals(m, pose)          bones posed at the substep's end
//! let momentum = begin_substep(m, g, h, d)  integrate, pin, λ = 0
//! for it in 0..iterations:
//!     (publish the targeted muscles' snapshots)
//!     closest_data(m, targets, schedule)
//!     project_iteration(m, method, order, targets, 1/h², parallel, it == 0)
//! end_substep(m, h, momentum)               v = (p − x)/h, x = p
//! ```
//!
//! Targets are looked up through [`TargetSet`]: the solver passes its table
//! (`m.target_ids` index it), another driver a slice of references in the
//! muscle's own target order (`m.target_ids = 0..k`).

use super::coloring::PlanKind;
pub use super::link::link_muscle;
use super::momentum::{self, RigidMomentum};
use super::{ColorScope, SolverMethod, coloring, jacobi};
use crate::closest::{ClosestHit, NO_TRIANGLE, TargetSet, TargetSurface};
use crate::constraints::{ConstraintBatch, ConstraintKind};
use crate::muscle::Muscle;
use glam::{Affine3A, Vec3, Vec4};

/// Starts a substep: predicts positions (gravity, damping `(1 − d)^damping_exp`),
/// moves pinned particles to their goals and zeroes the multipliers. Returns
/// the momentum to restore at [`end_substep`] for a free muscle (no
/// attachments, no targets), else `None`.
pub fn begin_substep(
    m: &mut Muscle,
    gravity: Vec3,
    h: f32,
    damping_exp: f32,
) -> Option<RigidMomentum> {
    integrate(m, gravity, h, damping_exp);
    m.place_pinned();
    m.constraints.clear_lambdas();
    momentum::is_free(m).then(|| momentum::measure(m))
}

/// Ends a substep: velocities from the corrections, positions accepted, and
/// the momentum `begin_substep` recorded restored.
pub fn end_substep(m: &mut Muscle, h: f32, momentum: Option<RigidMomentum>) {
    apply_predictions(m, h);
    if let Some(reference) = momentum {
        momentum::restore(m, reference, h);
    }
}

/// Publishes `m`'s predictions into `target`, the snapshot other muscles
/// read it through; `first_iteration` also updates normals and refits the
/// BVH when its slack asks for it.
pub fn publish(target: &mut TargetSurface, m: &Muscle, first_iteration: bool) {
    target.publish(&m.p[..m.surface_count]);
    if first_iteration {
        target.update_normals();
        target.refit(false);
        target.set_inverse_masses(&m.w[..m.surface_count]);
    }
}

/// Moves every attachment goal to its bone's pose: `pose(bone)` is the bone's
/// world transform at the substep (`None`: the world).
pub fn update_attachment_goals(m: &mut Muscle, pose: &impl Fn(Option<usize>) -> Affine3A) {
    let mut k = 0;
    for (i, a) in m.attachments.iter().enumerate() {
        let t = pose(a.bone);
        m.constraints.attach.goal[i] = t.transform_point3(a.vertex_local);
        if a.internal_particle.is_some() {
            m.constraints.branch_attach.goal[k] = t.transform_point3(a.internal_local);
            k += 1;
        }
    }
}

/// Explicit Euler prediction with gravity and per-substep damping.
fn integrate(m: &mut Muscle, gravity: Vec3, h: f32, damping_exp: f32) {
    let keep = (1.0 - m.params.damping).powf(damping_exp);
    for i in 0..m.x.len() {
        let v = (m.v[i] + h * gravity) * keep;
        m.v[i] = v;
        m.p[i] = m.x[i] + h * v;
    }
}

/// `v = (p − x)/h`, `x = p`.
fn apply_predictions(m: &mut Muscle, h: f32) {
    let inv_h = 1.0 / h;
    for i in 0..m.x.len() {
        m.v[i] = (m.p[i] - m.x[i]) * inv_h;
        m.x[i] = m.p[i];
    }
}

/// Which vertices run the full closest-point search in an iteration.
#[derive(Clone, Copy, Debug)]
pub struct ClosestSchedule {
    /// Frame counter (staggers the vertices).
    pub frame: u64,
    /// Frames between two full searches of one vertex.
    pub interval: u32,
    /// Frames between two choices of a vertex's closest target (a vertex
    /// with a full search also chooses).
    pub choose_interval: u32,
    /// Later iterations project onto the feature the walk found
    /// ([`crate::solver::SolverSettings::feature_contacts`]).
    pub feature_contacts: bool,
    /// The first iteration of a frame: full searches run, and vertices
    /// re-choose their closest target (one in `choose_interval`).
    pub active: bool,
    /// Walk from the last triangle (else re-project onto it).
    pub walk: bool,
    /// The first iteration of a substep: bones have just been posed.
    pub substep_start: bool,
    /// Split the vertices over the current rayon pool (same result).
    pub parallel: bool,
}

impl ClosestSchedule {
    /// Every vertex, every target: the full search.
    #[cfg(test)]
    pub const ALWAYS: Self = Self {
        frame: 0,
        interval: 1,
        choose_interval: 1,
        feature_contacts: false,
        active: true,
        walk: true,
        substep_start: true,
        parallel: false,
    };

    fn wants(&self, vertex: usize) -> bool {
        self.active && (vertex as u64 + self.frame).is_multiple_of(self.interval as u64)
    }

    fn chooses(&self, vertex: usize) -> bool {
        self.active && (vertex as u64 + self.frame).is_multiple_of(self.choose_interval as u64)
            || self.wants(vertex)
    }
}

/// Sliding constraints per parallel chunk of the closest-data block (a few
/// hundred ns each, so a chunk is worth a fork and join).
pub const CLOSEST_CHUNK: usize = 256;

/// Closest data (BE5): Sliding's closest point on the closest target per
/// vertex, and the current goals of Soft and Hard on their rest triangles.
/// With `search.parallel` the vertices are split over the current rayon pool
/// in chunks of [`CLOSEST_CHUNK`] (each vertex writes only its own data, so
/// the result is the same).
pub fn closest_data<T: TargetSet + Sync + ?Sized>(
    m: &mut Muscle,
    targets: &T,
    search: ClosestSchedule,
) {
    use rayon::prelude::*;
    let nt = m.target_ids.len();
    if nt == 0 {
        return;
    }
    let c = &mut m.constraints;
    let input = SlidingInput {
        p: &m.p,
        target_ids: &m.target_ids,
        targets,
        search,
        reach: m.params.contact_reach,
    };
    let run = SlidingRun::of(&mut c.sliding, &mut m.warm);
    if search.parallel && run.particle.len() > CLOSEST_CHUNK {
        run.split(CLOSEST_CHUNK, nt)
            .into_par_iter()
            .for_each(|run| input.closest(run));
    } else {
        input.closest(run);
    }
    // Soft and Hard goals on a rigid target only move with its bone, which
    // is posed once per substep; a muscle target moves every iteration.
    let moved = |t: &TargetSurface| search.substep_start || t.is_deforming();
    // Disabled instances (weight 0: infinite compliance) need no goal.
    for (i, a) in c.soft_anchor.iter().enumerate() {
        if c.soft.compliance[i].is_finite() {
            let t = targets.target(m.target_ids[a.target as usize]);
            if moved(t) {
                c.soft.goal[i] = t.point_at(a.triangle, a.barycentric);
                c.soft.target_w[i] = t.point_inverse_mass(a.triangle, a.barycentric);
            }
        }
    }
    for (i, a) in c.hard_anchor.iter().enumerate() {
        if c.hard.compliance[i].is_finite() {
            let t = targets.target(m.target_ids[a.target as usize]);
            if moved(t) {
                c.hard.goal[i] = t.point_in_frame(a.triangle, a.barycentric, a.local);
                c.hard.target_w[i] = t.point_inverse_mass(a.triangle, a.barycentric);
            }
        }
    }
}

/// A run of Sliding constraints' closest data: the batch's slices for the
/// run, and its warm cells (`targets` per constraint).
struct SlidingRun<'a> {
    particle: &'a [u32],
    connected: &'a [bool],
    rest_gap: &'a [f32],
    point: &'a mut [Vec3],
    target_w: &'a mut [f32],
    normal: &'a mut [Vec3],
    target: &'a mut [u32],
    triangle: &'a mut [u32],
    barycentric: &'a mut [Vec3],
    plane: &'a mut [Vec3],
    warm: &'a mut [u32],
}

impl<'a> SlidingRun<'a> {
    /// The whole batch, with the muscle's warm cells.
    fn of(s: &'a mut crate::constraints::SlidingBatch, warm: &'a mut [u32]) -> Self {
        Self {
            particle: &s.particle,
            connected: &s.connected,
            rest_gap: &s.rest_gap,
            point: &mut s.point,
            target_w: &mut s.target_w,
            normal: &mut s.normal,
            target: &mut s.target,
            triangle: &mut s.triangle,
            barycentric: &mut s.barycentric,
            plane: &mut s.plane,
            warm,
        }
    }

    /// Runs of `k` constraints (the last one shorter); `targets` warm cells
    /// per constraint.
    fn split(mut self, k: usize, targets: usize) -> Vec<Self> {
        fn front<'a, T>(slice: &mut &'a mut [T], k: usize) -> &'a mut [T] {
            let (head, tail) = std::mem::take(slice).split_at_mut(k);
            *slice = tail;
            head
        }
        fn front_ref<'a, T>(slice: &mut &'a [T], k: usize) -> &'a [T] {
            let (head, tail) = slice.split_at(k);
            *slice = tail;
            head
        }
        let mut runs = Vec::new();
        while self.particle.len() > k {
            runs.push(Self {
                particle: front_ref(&mut self.particle, k),
                connected: front_ref(&mut self.connected, k),
                rest_gap: front_ref(&mut self.rest_gap, k * targets),
                point: front(&mut self.point, k),
                target_w: front(&mut self.target_w, k),
                normal: front(&mut self.normal, k),
                target: front(&mut self.target, k),
                triangle: front(&mut self.triangle, k),
                barycentric: front(&mut self.barycentric, k),
                plane: front(&mut self.plane, k),
                warm: front(&mut self.warm, k * targets),
            });
        }
        runs.push(self);
        runs
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

/// What the Sliding part of closest data reads.
struct SlidingInput<'a, T: ?Sized> {
    p: &'a [Vec3],
    target_ids: &'a [usize],
    targets: &'a T,
    search: ClosestSchedule,
    /// The muscle's contact reach: a target farther than this at rest is
    /// never chosen.
    reach: f32,
}

impl<T: TargetSet + ?Sized> SlidingInput<'_, T> {
    /// Closest points for a run of Sliding constraints.
    fn closest(&self, run: SlidingRun) {
        let SlidingRun {
            particle,
            connected,
            rest_gap,
            point,
            target_w,
            normal,
            target,
            triangle,
            barycentric,
            plane,
            warm,
        } = run;
        let (nt, search) = (self.target_ids.len(), self.search);
        for i in 0..particle.len() {
            if !connected[i] {
                continue;
            }
            let v = particle[i] as usize;
            let q = self.p[v];
            let first = target[i] as usize;
            let choose = search.chooses(v) || first >= nt;
            // Later iterations project the vertex onto the feature (face
            // plane, edge or corner) of the triangle the walk found: the
            // closest point while the vertex stays in that feature's region.
            if !choose && !search.walk && search.feature_contacts {
                let surface = self.targets.target(self.target_ids[first]);
                point[i] = surface.on_feature(q, triangle[i], barycentric[i], plane[i]);
                continue;
            }
            // Last iteration's target first. The vertex re-chooses in the
            // first iteration of one frame in `choose_interval` (staggered
            // over vertices); in between it keeps its target but, in the
            // first iteration of a frame, still checks every bone whose box
            // it is in (it may have entered one).
            let bones_only = !choose;
            let order = (first < nt)
                .then_some(first)
                .into_iter()
                .chain((0..nt).filter(move |&s| (choose || search.active) && s != first));
            let full = search.wants(v);
            let mut best: Option<(Claim, ClosestHit, u32)> = None;
            for slot in order {
                let gap = rest_gap[i * nt + slot];
                let surface = self.targets.target(self.target_ids[slot]);
                // A target out of the vertex's contact band at rest (or
                // across a seam, see `link_muscle`) is never chosen.
                if gap > self.reach || bones_only && slot != first && surface.is_deforming() {
                    continue;
                }
                // Only a hit nearer than `bound` can claim the vertex.
                let bound = match &best {
                    None => f32::MAX,
                    Some((claim, _, _)) => {
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
                let cell = &mut warm[i * nt + slot];
                let last = (*cell != NO_TRIANGLE).then_some(*cell);
                let local = last.filter(|_| !full).and_then(|t| {
                    if search.walk {
                        surface.walk(q, t)
                    } else {
                        surface.on_triangle(q, t)
                    }
                });
                let Some(hit) = local.or_else(|| surface.closest_within(q, last, bound)) else {
                    continue;
                };
                *cell = hit.triangle;
                let claim = if hit.signed_distance < 0.0 && !surface.is_deforming() {
                    Claim::InsideBone(-hit.distance)
                } else {
                    Claim::Gap(hit.distance - gap)
                };
                if best
                    .as_ref()
                    .is_none_or(|(b, _, _)| claim.beats(b, self.reach))
                {
                    best = Some((claim, hit, slot as u32));
                }
            }
            match best {
                Some((_, hit, slot)) => {
                    let surface = self.targets.target(self.target_ids[slot as usize]);
                    point[i] = hit.point;
                    target_w[i] = surface.point_inverse_mass(hit.triangle, hit.barycentric);
                    normal[i] = hit.normal;
                    triangle[i] = hit.triangle;
                    barycentric[i] = hit.barycentric;
                    // Only the feature projection reads the plane; it runs
                    // after a first iteration that comes here.
                    if search.feature_contacts {
                        plane[i] = surface.face_normal(hit.triangle);
                    }
                    target[i] = slot;
                }
                None => target[i] = u32::MAX,
            }
        }
    }
}

/// One iteration's projection of a muscle: every type in `order` but a
/// trailing Volume, then the bone contacts, then the Volume (which keeps the
/// volume exact while moving vertices far less than the contacts did).
/// `substep_start`: the first iteration of a substep, where a coloured
/// method checks its plan against the muscle's topology (a host may have
/// edited it since the last step).
pub fn project_iteration<T: TargetSet + ?Sized>(
    m: &mut Muscle,
    method: SolverMethod,
    order: &[ConstraintKind],
    targets: &T,
    inv_h2: f32,
    parallel: bool,
    substep_start: bool,
) {
    match method {
        SolverMethod::Sequential => {
            let (body, _) = split_volume(order);
            project(m, body, inv_h2);
        }
        SolverMethod::Colored { .. } | SolverMethod::Hybrid { .. } => {
            let (kind, omega) = plan_kind(method).expect("a coloured method");
            coloring::project_colored(m, order, kind, inv_h2, omega, parallel, substep_start);
            volume_within(m, order, inv_h2, parallel);
        }
        SolverMethod::Jacobi { omega } => {
            let mut state = m
                .jacobi
                .take()
                .unwrap_or_else(|| jacobi::JacobiState::new(m, order));
            jacobi::project_jacobi(m, &mut state, inv_h2, omega, parallel);
            m.jacobi = Some(state);
            volume_within(m, order, inv_h2, parallel);
        }
    }
    finish_iteration(m, order, targets, inv_h2, parallel, substep_start);
}

/// The colour plan a method runs on and its Jacobi ω (1 without a tail);
/// `None` for the uncoloured methods.
pub fn plan_kind(method: SolverMethod) -> Option<(PlanKind, f32)> {
    match method {
        SolverMethod::Colored {
            scope: ColorScope::PerMuscle,
        } => Some((PlanKind::PerConstraint, 1.0)),
        SolverMethod::Colored {
            scope: ColorScope::Global,
        } => Some((PlanKind::Clustered, 1.0)),
        SolverMethod::Hybrid { min_group, omega } => Some((PlanKind::Hybrid { min_group }, omega)),
        SolverMethod::Sequential | SolverMethod::Jacobi { .. } => None,
    }
}

/// `order` without a trailing Volume, and whether it had one.
fn split_volume(order: &[ConstraintKind]) -> (&[ConstraintKind], bool) {
    match order.split_last() {
        Some((ConstraintKind::Volume, rest)) => (rest, true),
        _ => (order, false),
    }
}

/// After a coloured or Jacobi sweep (which leave Volume out): the Volume,
/// when `order` has it anywhere but last.
pub(super) fn volume_within(m: &mut Muscle, order: &[ConstraintKind], inv_h2: f32, parallel: bool) {
    if !split_volume(order).1 && order.contains(&ConstraintKind::Volume) {
        project_volume(m, inv_h2, parallel);
    }
}

/// The end of an iteration's projection: the bone contacts, then the Volume
/// when `order` ends with it. `parallel`: a large muscle's Volume runs as a
/// parallel reduction on the current rayon pool (same result).
pub fn finish_iteration<T: TargetSet + ?Sized>(
    m: &mut Muscle,
    order: &[ConstraintKind],
    targets: &T,
    inv_h2: f32,
    parallel: bool,
    substep_start: bool,
) {
    bone_contacts(m, targets, substep_start);
    if split_volume(order).1 {
        project_volume(m, inv_h2, parallel);
    }
}

/// Projects the Volume constraint of `m`, if it has one (a large mesh's
/// evaluation as a parallel reduction when `parallel`, same result).
fn project_volume(m: &mut Muscle, inv_h2: f32, parallel: bool) {
    if let Some(v) = &mut m.constraints.volume {
        v.solve_with(&mut m.p, &m.w, inv_h2, parallel);
    }
}

/// In each iteration, after the projections (before a trailing Volume), puts
/// every surface vertex that ended up inside one of its muscle's bone targets
/// (and was outside it at rest) back on the bone's surface: bones do not give
/// way, whatever the soft constraints solved after Sliding did. Each bone is
/// checked only for vertices inside its bounding box, from the last closest
/// triangle (a walk), and not at all while the vertex stays within its last
/// known clearance of where it had it ([`Muscle::clearance`]). Bones do not
/// move within a substep, so after its first iteration (`substep_start`) a
/// vertex that stayed within the smallest of its cells' remaining clearances
/// ([`Muscle::bone_margin`]) skips every cell at once: the cells would all
/// have been skipped.
pub fn bone_contacts<T: TargetSet + ?Sized>(m: &mut Muscle, targets: &T, substep_start: bool) {
    let nt = m.target_ids.len();
    let c = &m.constraints.sliding;
    if nt == 0 || !c.rigid.iter().any(|&r| r) {
        return;
    }
    if m.bone_margin.len() != c.len() {
        m.bone_margin = vec![Vec4::ZERO; c.len()];
    }
    for i in 0..c.len() {
        let v = c.particle[i] as usize;
        if m.w[v] == 0.0 {
            continue;
        }
        let anchor = m.bone_margin[i];
        if !substep_start && m.p[v].distance_squared(anchor.truncate()) < anchor.w * anchor.w {
            continue;
        }
        // The smallest remaining clearance over this vertex's bones.
        let mut margin = f32::INFINITY;
        for slot in (0..nt).filter(|&s| c.rigid[s]) {
            let cell = i * nt + slot;
            if !c.rest_outside[cell] {
                continue;
            }
            let target = targets.target(m.target_ids[slot]);
            let local = target.to_local(m.p[v]);
            let known = m.clearance[cell];
            let moved2 = local.distance_squared(known.truncate());
            if moved2 < known.w * known.w {
                margin = margin.min(known.w - moved2.sqrt());
                continue;
            }
            let lower = target.lower_bound_local(local);
            if lower > 0.0 {
                m.clearance[cell] = local.extend(lower);
                margin = margin.min(lower);
                continue;
            }
            let last = &mut m.warm[cell];
            let q = m.p[v];
            let hit = match *last {
                NO_TRIANGLE => target.closest_within(q, None, f32::INFINITY),
                t => target.walk(q, t),
            };
            margin = 0.0;
            if let Some(hit) = hit {
                *last = hit.triangle;
                if hit.signed_distance < 0.0 {
                    m.p[v] -= hit.normal * hit.signed_distance;
                    m.clearance[cell] = Vec4::ZERO;
                } else {
                    m.clearance[cell] = local.extend(hit.distance);
                }
            }
        }
        // A little less than the exact margin, so that rounding never skips
        // a cell the per-cell test would have checked.
        let margin = if margin.is_finite() {
            (margin * (1.0 - 1e-3) - 1e-6).max(0.0)
        } else {
            f32::INFINITY
        };
        m.bone_margin[i] = m.p[v].extend(margin);
    }
}

/// Projects every constraint of `m` once, type by type in `order` (BE6).
pub fn project(m: &mut Muscle, order: &[ConstraintKind], inv_h2: f32) {
    let (p, w, c) = (&mut m.p, &m.w, &mut m.constraints);
    for &kind in order {
        match kind {
            ConstraintKind::Attach => c.attach.solve(p, w, inv_h2),
            ConstraintKind::BranchAttach => c.branch_attach.solve(p, w, inv_h2),
            ConstraintKind::Hard => c.hard.solve(p, w, inv_h2),
            ConstraintKind::Soft => c.soft.solve(p, w, inv_h2),
            ConstraintKind::Sliding => c.sliding.solve(p, w, inv_h2),
            ConstraintKind::Branch => c.branch.solve(p, w, inv_h2),
            ConstraintKind::Internal => c.internal.solve(p, w, inv_h2),
            ConstraintKind::Fiber => c.fiber.solve(p, w, inv_h2),
            ConstraintKind::Volume => {
                if let Some(v) = &mut c.volume {
                    v.solve(p, w, inv_h2);
                }
            }
        }
    }
}
